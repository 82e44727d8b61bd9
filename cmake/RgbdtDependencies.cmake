# Every third-party dependency is found here, once, from Debian's packages
# (scripts/install-deps installs them). Modules link the imported targets; the
# rgbdt_find_for() table at the end says how an installed rgbdt finds each of them again,
# so rgbdtConfig.cmake asks for what a component's link interface names and nothing else.
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(yaml-cpp REQUIRED)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs calib3d features2d)
find_package(Ceres 2 REQUIRED)
# Debian's VTK (pulled in by PCL) refers to MPI::MPI_C; find it first.
find_package(MPI COMPONENTS C)
find_package(PCL 1.12 REQUIRED COMPONENTS common io search kdtree sample_consensus segmentation filters features registration)
find_package(octomap REQUIRED)
# Header-only k-d tree for rgbdt_map's registration (also a dependency of MRPT's math).
find_package(nanoflann REQUIRED)
find_package(mrpt-hwdrivers QUIET)
find_package(mrpt-obs QUIET)
find_package(mrpt-maps QUIET)
find_package(mrpt-slam QUIET)
find_package(PkgConfig REQUIRED)
pkg_check_modules(ARAVIS IMPORTED_TARGET aravis-0.8)
pkg_check_modules(LIBUSB IMPORTED_TARGET libusb-1.0)
find_package(CLI11 QUIET)
if(RGBDT_BUILD_TESTS)
  find_package(GTest REQUIRED)
  include(GoogleTest)
endif()
if(RGBDT_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()

# PCL exports include directories and definitions as variables; wrap them in one target
# so modules link a target like every other dependency.
if(NOT TARGET rgbdt_pcl)
  add_library(rgbdt_pcl INTERFACE)
  # Only the PCL libraries we use: ${PCL_LIBRARIES} would also link all of VTK.
  target_include_directories(rgbdt_pcl SYSTEM INTERFACE ${PCL_INCLUDE_DIRS})
  target_link_libraries(rgbdt_pcl INTERFACE pcl_common pcl_io pcl_search pcl_kdtree
    pcl_sample_consensus pcl_segmentation pcl_filters pcl_features pcl_registration)
endif()

# rgbdt_find_for(TARGETS <imported targets...> FIND <lines...>): the lines rgbdtConfig.cmake
# runs for a component whose link interface names one of these targets. A module that
# links an imported target missing from this table stops the configure (see
# rgbdt_install_package), so the installed package cannot fall behind the modules.
function(rgbdt_find_for)
  cmake_parse_arguments(ARG "" "" "TARGETS;FIND" ${ARGN})
  foreach(t IN LISTS ARG_TARGETS)
    set_property(GLOBAL PROPERTY "RGBDT_FIND_FOR_${t}" "${ARG_FIND}")
  endforeach()
endfunction()

rgbdt_find_for(TARGETS Threads::Threads FIND "find_dependency(Threads)")
rgbdt_find_for(TARGETS Eigen3::Eigen FIND "find_dependency(Eigen3 NO_MODULE)")
rgbdt_find_for(TARGETS yaml-cpp FIND "find_dependency(yaml-cpp)")
rgbdt_find_for(TARGETS ${OpenCV_LIBS} opencv_core opencv_imgproc opencv_imgcodecs opencv_calib3d opencv_features2d
  FIND "find_dependency(OpenCV)")
rgbdt_find_for(TARGETS Ceres::ceres FIND "find_dependency(Ceres)")
rgbdt_find_for(TARGETS nanoflann::nanoflann FIND "find_dependency(nanoflann)")
rgbdt_find_for(TARGETS rgbdt_pcl FIND
  "find_package(MPI QUIET COMPONENTS C)"
  "find_dependency(PCL COMPONENTS common io search kdtree sample_consensus segmentation filters features registration)"
  "if(NOT TARGET rgbdt_pcl)"
  "  include(\${CMAKE_CURRENT_LIST_DIR}/rgbdt-pcl-targets.cmake)"
  "endif()")
foreach(part IN ITEMS obs hwdrivers maps slam io serialization)
  rgbdt_find_for(TARGETS mrpt::${part} FIND "find_dependency(mrpt-${part})")
endforeach()
rgbdt_find_for(TARGETS PkgConfig::ARAVIS FIND
  "find_dependency(PkgConfig)" "pkg_check_modules(ARAVIS REQUIRED IMPORTED_TARGET aravis-0.8)")
rgbdt_find_for(TARGETS PkgConfig::LIBUSB FIND
  "find_dependency(PkgConfig)" "pkg_check_modules(LIBUSB REQUIRED IMPORTED_TARGET libusb-1.0)")
