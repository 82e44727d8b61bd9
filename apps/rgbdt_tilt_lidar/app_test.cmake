# End-to-end check of the app as a user runs it (ctest -P script):
#   record 3 s from the emulated rig -> info -> assemble (rig found beside the rawlog)
# Expects: about 40 scans/s and 200 encoder samples/s in the rawlog, no loss reported, and at
# least 3 whole tilts written (a 3 s sweep at the default 1 Hz tilt rate holds 4-6 reversals).
# Run as: cmake -DAPP=<rgbdt_tilt_lidar> -DWORK=<dir> -DRIG_INI=<rig.ini> -P app_test.cmake
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")

function(run_step name)
  execute_process(COMMAND ${ARGN} WORKING_DIRECTORY "${WORK}" RESULT_VARIABLE rc
                  OUTPUT_VARIABLE out ERROR_VARIABLE err)
  set(${name}_out "${out}" PARENT_SCOPE)
  set(${name}_err "${err}" PARENT_SCOPE)
  set(${name}_rc "${rc}" PARENT_SCOPE)
endfunction()

run_step(record "${APP}" record --config "${RIG_INI}" --out "${WORK}/s.rawlog" --emulate --duration 3)
if(NOT record_rc EQUAL 0)
  message(FATAL_ERROR "record failed (${record_rc}):\n${record_out}\n${record_err}")
endif()
if(NOT record_out MATCHES "recorded [0-9]+ records: ([0-9]+) scans \\(([0-9]+) missed\\), ([0-9]+) encoder samples \\(([0-9]+) failed reads\\)")
  message(FATAL_ERROR "record printed no final statistics:\n${record_out}")
endif()
set(scans ${CMAKE_MATCH_1})
set(encoder ${CMAKE_MATCH_3})
# 3 s at 40 scans/s and 200 samples/s; a loaded CI machine may lose the first scan period
# while the scanner starts, so allow 10 % below the nominal counts.
if(scans LESS 108 OR encoder LESS 540)
  message(FATAL_ERROR "expected ~120 scans and ~600 encoder samples in 3 s, got ${scans} and ${encoder}")
endif()
if(NOT EXISTS "${WORK}/s.tilt_rig.yaml")
  message(FATAL_ERROR "record did not write s.tilt_rig.yaml beside the rawlog")
endif()

run_step(info "${APP}" info "${WORK}/s.rawlog")
if(NOT info_rc EQUAL 0 OR NOT info_out MATCHES "HOKUYO +mrpt::obs::CObservation2DRangeScan +${scans} ")
  message(FATAL_ERROR "info does not list the ${scans} HOKUYO scans (${info_rc}):\n${info_out}\n${info_err}")
endif()

run_step(asm "${APP}" assemble "${WORK}/s.rawlog" --out "${WORK}/asm")
if(NOT asm_rc EQUAL 0)
  message(FATAL_ERROR "assemble failed (${asm_rc}):\n${asm_out}\n${asm_err}")
endif()
file(GLOB pcds "${WORK}/asm/clouds/*.pcd")
list(LENGTH pcds n_pcd)
file(STRINGS "${WORK}/asm/clouds/index.csv" index_lines)
list(LENGTH index_lines n_index)
if(n_pcd LESS 3 OR NOT n_index GREATER n_pcd)  # index.csv has a header line
  message(FATAL_ERROR "expected >= 3 tilt clouds with an index, got ${n_pcd} PCDs, ${n_index} index lines:\n${asm_out}")
endif()

# Without the rig file the message names the file it looked for.
file(RENAME "${WORK}/s.tilt_rig.yaml" "${WORK}/moved.yaml")
run_step(norig "${APP}" assemble "${WORK}/s.rawlog" --out "${WORK}/asm2")
if(norig_rc EQUAL 0 OR NOT norig_err MATCHES "s\\.tilt_rig\\.yaml")
  message(FATAL_ERROR "assemble without a rig should fail naming s.tilt_rig.yaml (${norig_rc}):\n${norig_err}")
endif()
message(STATUS "rgbdt_tilt_lidar: ${scans} scans, ${encoder} encoder samples, ${n_pcd} tilts")
