# rgbdt_add_module(), rgbdt_add_tests(), rgbdt_add_benchmark(), rgbdt_add_app() and
# rgbdt_install_package(): one place that sets the standard, warnings, sanitizers,
# output folders and install rules, so each module's CMakeLists is a few lines.
include(CMakePackageConfigHelpers)

set_property(GLOBAL PROPERTY RGBDT_INSTALLED_MODULES "")

# Standard, warnings and (optionally) sanitizers for one target.
function(rgbdt_apply_standard target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF POSITION_INDEPENDENT_CODE ON)
  target_compile_options(${target} PRIVATE
    $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wno-unused-parameter>)
  if(RGBDT_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer
                                             -fno-sanitize-recover=undefined)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()

# rgbdt_add_module(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Creates library rgbdt_<name>, alias rgbdt::<name>, headers from include/, installed
# and exported as rgbdt::<name>.
function(rgbdt_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  set(target rgbdt_${name})
  add_library(${target} ${ARG_SOURCES})
  add_library(rgbdt::${name} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name} OUTPUT_NAME rgbdt_${name})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>
    PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  rgbdt_apply_standard(${target})
  install(TARGETS ${target} EXPORT rgbdt-${name}-targets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
    RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT rgbdt-${name}-targets NAMESPACE rgbdt::
    DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rgbdt)
  set_property(GLOBAL APPEND PROPERTY RGBDT_INSTALLED_MODULES ${name})
endfunction()

# rgbdt_use_test_support(<target>): the helpers every test shares (tests/support: rgbdt/test/
# test_util.hpp, process.hpp) and the folders a test uses (RGBDT_SOURCE_DIR, RGBDT_BINARY_DIR,
# RGBDT_SHARED_DATA_DIR). The folders come from one generated library, not from -D flags, so
# that the tests' object files are the same in every clone and ccache reuses them.
function(rgbdt_use_test_support target)
  if(NOT TARGET rgbdt_test_paths)
    configure_file(${PROJECT_SOURCE_DIR}/cmake/test_paths.cpp.in ${PROJECT_BINARY_DIR}/rgbdt_test_paths.cpp @ONLY)
    add_library(rgbdt_test_paths STATIC ${PROJECT_BINARY_DIR}/rgbdt_test_paths.cpp)
    rgbdt_apply_standard(rgbdt_test_paths)
  endif()
  target_link_libraries(${target} PRIVATE rgbdt_test_paths)
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR}/tests/support)
  target_compile_options(${target} PRIVATE -include ${PROJECT_SOURCE_DIR}/tests/support/rgbdt/test/paths.hpp)
endfunction()

# rgbdt_add_tests(<module> file_test.cpp ... [LIBS ...] [LABELS ...])
# One GoogleTest executable per file, named after the file, registered with CTest and
# labelled <module>, or <module>_<label>... with LABELS (one token: gtest_discover_tests
# writes its properties unquoted, so a list would split). ctest's -L and -LE take regular
# expressions, so `-L calib_targets` still selects calib_targets_slow. `slow` marks tests
# that take minutes in Release: CI runs them once, in Release, not again under the
# sanitizers.
function(rgbdt_add_tests module)
  if(NOT RGBDT_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "LIBS;LABELS" ${ARGN})
  set(label ${module})
  foreach(extra IN LISTS ARG_LABELS)
    string(APPEND label "_${extra}")
  endforeach()
  foreach(file IN LISTS ARG_UNPARSED_ARGUMENTS)
    get_filename_component(test_name ${file} NAME_WE)
    add_executable(${test_name} ${file})
    target_link_libraries(${test_name} PRIVATE rgbdt::${module} ${ARG_LIBS} GTest::gtest_main GTest::gmock)
    rgbdt_use_test_support(${test_name})
    rgbdt_apply_standard(${test_name})
    gtest_discover_tests(${test_name} DISCOVERY_TIMEOUT 60
      PROPERTIES LABELS ${label} ENVIRONMENT "RGBDT_BIN_DIR=${PROJECT_BINARY_DIR}/bin")
  endforeach()
endfunction()

# rgbdt_add_benchmark(<name> file.cpp ... LIBS ...): a Google Benchmark program in bin/.
function(rgbdt_add_benchmark name)
  if(NOT RGBDT_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "LIBS" ${ARGN})
  add_executable(${name} ${ARG_UNPARSED_ARGUMENTS})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} benchmark::benchmark)
  if(TARGET CLI11::CLI11)  # the bench programs that take options parse them as the apps do
    target_link_libraries(${name} PRIVATE CLI11::CLI11)
  endif()
  rgbdt_apply_standard(${name})
endfunction()

# rgbdt_add_app(<name> file.cpp ... LIBS ...): an installed command-line program.
function(rgbdt_add_app name)
  cmake_parse_arguments(ARG "" "" "LIBS" ${ARGN})
  add_executable(${name} ${ARG_UNPARSED_ARGUMENTS})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS})
  if(TARGET CLI11::CLI11)
    target_link_libraries(${name} PRIVATE CLI11::CLI11)
  endif()
  if(TARGET rgbdt_app_common)  # apps/common: --config FILE and the effective configuration
    target_link_libraries(${name} PRIVATE rgbdt_app_common)
  endif()
  rgbdt_apply_standard(${name})
  install(TARGETS ${name} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endfunction()

# Writes and installs rgbdtConfig.cmake so that other projects can say
#   find_package(rgbdt REQUIRED COMPONENTS core extrinsics)
# Each component's needs come from its target's link interface (what a consumer must be able
# to resolve): other rgbdt components, closed over in install order, and the find lines that
# rgbdt_find_for() gives its imported targets. Plain library names and paths need no find.
function(rgbdt_install_package)
  get_property(modules GLOBAL PROPERTY RGBDT_INSTALLED_MODULES)
  set(RGBDT_ALL_MODULES "${modules}")
  set(RGBDT_COMPONENT_DEPS "")
  set(RGBDT_COMPONENT_FINDS "")
  foreach(m IN LISTS modules)
    get_target_property(interface rgbdt_${m} INTERFACE_LINK_LIBRARIES)
    if(NOT interface)
      set(interface "")
    endif()
    set(deps "")
    set(lines "")
    foreach(item IN LISTS interface)
      string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" item "${item}")
      if(item MATCHES "^rgbdt::(.+)$")
        list(APPEND deps ${CMAKE_MATCH_1} ${_rgbdt_deps_${CMAKE_MATCH_1}})
        continue()
      endif()
      get_property(find_lines GLOBAL PROPERTY "RGBDT_FIND_FOR_${item}")
      if(find_lines)
        list(APPEND lines ${find_lines})
      elseif(TARGET ${item})
        message(FATAL_ERROR "rgbdt_${m} links ${item}, which cmake/RgbdtDependencies.cmake does not map "
                            "with rgbdt_find_for(): an installed rgbdt could not find it")
      endif()
    endforeach()
    # Dependencies first, in install order.
    set(ordered "")
    foreach(d IN LISTS modules)
      if(d IN_LIST deps)
        list(APPEND ordered ${d})
      endif()
    endforeach()
    set(_rgbdt_deps_${m} "${ordered}")
    list(REMOVE_DUPLICATES lines)
    string(APPEND RGBDT_COMPONENT_DEPS "set(_rgbdt_deps_${m} \"${ordered}\")\n")
    if(lines)
      string(APPEND RGBDT_COMPONENT_FINDS "list(FIND _rgbdt_load ${m} _idx)\nif(NOT _idx EQUAL -1)\n")
      foreach(line IN LISTS lines)
        string(APPEND RGBDT_COMPONENT_FINDS "  ${line}\n")
      endforeach()
      string(APPEND RGBDT_COMPONENT_FINDS "endif()\n")
    endif()
  endforeach()
  configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/rgbdtConfig.cmake.in
    ${PROJECT_BINARY_DIR}/rgbdtConfig.cmake
    INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rgbdt)
  write_basic_package_version_file(${PROJECT_BINARY_DIR}/rgbdtConfigVersion.cmake
    COMPATIBILITY SameMinorVersion)
  install(FILES ${PROJECT_BINARY_DIR}/rgbdtConfig.cmake ${PROJECT_BINARY_DIR}/rgbdtConfigVersion.cmake
    DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rgbdt)
  if(TARGET rgbdt_pcl)
    install(TARGETS rgbdt_pcl EXPORT rgbdt-pcl-targets)
    install(EXPORT rgbdt-pcl-targets DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rgbdt)
  endif()
endfunction()
