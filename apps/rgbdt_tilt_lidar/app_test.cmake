# End-to-end check of the app as a user runs it (ctest -P script):
#   record 3 s from the emulated rig (from rig.ini, and from the YAML option file without an
#   INI) -> info -> assemble (rig found beside the rawlog), an option over the INI's key, the
#   INI given to --config, missing rig options, relative --out from another directory, Ctrl-C,
#   gzip garbage, both rig file names
# Expects: about 40 scans/s and 200 encoder samples/s in the rawlog, no loss reported, and at
# least 3 whole tilts written (a 3 s sweep at the default 1 Hz tilt rate holds 4-6 reversals).
# Run as: cmake -DAPP=<rgbdt_tilt_lidar> -DWORK=<dir> -DRIG_INI=<rig.ini>
#   -DRIG_YAML=<config/tilt_lidar_paper_rig.yaml> -P app_test.cmake
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")

function(run_step name)
  execute_process(COMMAND ${ARGN} WORKING_DIRECTORY "${WORK}" RESULT_VARIABLE rc
                  OUTPUT_VARIABLE out ERROR_VARIABLE err)
  set(${name}_out "${out}" PARENT_SCOPE)
  set(${name}_err "${err}" PARENT_SCOPE)
  set(${name}_rc "${rc}" PARENT_SCOPE)
endfunction()

# Records 3 s from the emulated rig into WORK/<stem>.rawlog with the record options in ARGN,
# and checks the statistics, the rig file beside the rawlog and what `info` lists; sets
# <stem>_scans and <stem>_encoder.
function(record_and_check stem)
  run_step(record "${APP}" ${ARGN} --out "${WORK}/${stem}.rawlog" --emulate --duration 3)
  string(JOIN " " args ${ARGN})
  if(NOT record_rc EQUAL 0)
    message(FATAL_ERROR "${args} failed (${record_rc}):\n${record_out}\n${record_err}")
  endif()
  if(NOT record_out MATCHES "recorded [0-9]+ records: ([0-9]+) scans \\(([0-9]+) missed\\), ([0-9]+) encoder samples \\(([0-9]+) failed reads\\)")
    message(FATAL_ERROR "${args} printed no final statistics:\n${record_out}")
  endif()
  set(scans ${CMAKE_MATCH_1})
  set(encoder ${CMAKE_MATCH_3})
  # 3 s at 40 scans/s and 200 samples/s; a loaded CI machine may lose the first scan period
  # while the scanner starts, so allow 10 % below the nominal counts.
  if(scans LESS 108 OR encoder LESS 540)
    message(FATAL_ERROR "${args}: expected ~120 scans and ~600 encoder samples in 3 s, got ${scans} and ${encoder}")
  endif()
  if(NOT EXISTS "${WORK}/${stem}.tilt_rig.yaml")
    message(FATAL_ERROR "${args} did not write ${stem}.tilt_rig.yaml beside the rawlog")
  endif()
  run_step(info "${APP}" info "${WORK}/${stem}.rawlog")
  if(NOT info_rc EQUAL 0 OR NOT info_out MATCHES "HOKUYO +mrpt::obs::CObservation2DRangeScan +${scans} ")
    message(FATAL_ERROR "info does not list the ${scans} HOKUYO scans of ${stem}.rawlog (${info_rc}):\n${info_out}\n${info_err}")
  endif()
  set(${stem}_scans ${scans} PARENT_SCOPE)
  set(${stem}_encoder ${encoder} PARENT_SCOPE)
endfunction()

record_and_check(s record --ini "${RIG_INI}")
set(scans ${s_scans})
set(encoder ${s_encoder})

# The paper's rig from the YAML option file alone (no INI): the same rig file as rig.ini's.
record_and_check(paper --config "${RIG_YAML}" record)
file(READ "${WORK}/s.tilt_rig.yaml" ini_rig)
file(READ "${WORK}/paper.tilt_rig.yaml" yaml_rig)
if(NOT ini_rig STREQUAL yaml_rig)
  message(FATAL_ERROR "${RIG_YAML} and ${RIG_INI} describe one rig, but the rig files differ:\n${yaml_rig}\n${ini_rig}")
endif()

# An option over the INI's key: the mount's z from the command line, the rest from the INI.
run_step(over "${APP}" record --ini "${RIG_INI}" --mount-z 0.125 --out "${WORK}/over.rawlog" --emulate --duration 1)
file(READ "${WORK}/over.tilt_rig.yaml" over_rig)
if(NOT over_rc EQUAL 0 OR NOT over_rig MATCHES "translation: \\[0, 0, 0\\.125\\]"
   OR NOT over_rig MATCHES "counts_per_revolution: 501923")
  message(FATAL_ERROR "record --ini rig.ini --mount-z 0.125 (${over_rc}) should write that mount:\n${over_rig}\n${over_err}")
endif()

# Without --ini and without the rig's options: an error that names what is missing, and no
# output.
run_step(bare "${APP}" record --dxl-id 1 --out "${WORK}/bare.rawlog")
if(bare_rc EQUAL 0 OR NOT bare_err MATCHES "missing: --scanner-ip or --scanner-serial, --dxl-port, --dxl-baud, --dxl-counts-per-rev, --tilt-min-deg"
   OR bare_err MATCHES "--dxl-id," OR EXISTS "${WORK}/bare.rawlog" OR EXISTS "${WORK}/bare.tilt_rig.yaml")
  message(FATAL_ERROR "record without --ini or rig options should fail naming them (${bare_rc}):\n${bare_out}\n${bare_err}")
endif()

# The INI given to --config (where `record` took it before --config became the app's YAML
# option file), before or after the command: an error that says the INI goes to --ini.
foreach(order IN ITEMS before after)
  if(order STREQUAL before)
    run_step(old "${APP}" --config "${RIG_INI}" record --out "${WORK}/old.rawlog" --emulate --duration 1)
  else()
    run_step(old "${APP}" record --config "${RIG_INI}" --out "${WORK}/old.rawlog" --emulate --duration 1)
  endif()
  if(old_rc EQUAL 0 OR NOT old_err MATCHES "looks like an INI file \\(line [0-9]+: \\[TILT_LIDAR\\]\\).*`record --ini FILE`"
     OR EXISTS "${WORK}/old.rawlog")
    message(FATAL_ERROR "--config rig.ini (${order} record) should fail pointing to record --ini (${old_rc}):\n${old_out}\n${old_err}")
  endif()
endforeach()

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

# Index rows resolve against the index's folder, also with a relative --out given from
# another working directory (readers resolve rows against the folder of index.csv).
function(check_index index)
  get_filename_component(dir "${index}" DIRECTORY)
  file(STRINGS "${index}" rows)
  list(LENGTH rows n)
  if(n LESS 2)
    message(FATAL_ERROR "${index} lists no clouds")
  endif()
  list(REMOVE_AT rows 0)
  foreach(row IN LISTS rows)
    string(REGEX REPLACE "^[^,]*," "" f "${row}")
    if(NOT IS_ABSOLUTE "${f}")
      set(f "${dir}/${f}")
    endif()
    if(NOT EXISTS "${f}")
      message(FATAL_ERROR "${index}: row '${row}' names ${f}, which does not exist")
    endif()
  endforeach()
endfunction()
file(MAKE_DIRECTORY "${WORK}/elsewhere")
execute_process(COMMAND "${APP}" assemble "${WORK}/s.rawlog" --out rel/asm WORKING_DIRECTORY "${WORK}/elsewhere"
                RESULT_VARIABLE rel_rc OUTPUT_VARIABLE rel_out ERROR_VARIABLE rel_err)
if(NOT rel_rc EQUAL 0)
  message(FATAL_ERROR "assemble --out rel/asm failed (${rel_rc}):\n${rel_out}\n${rel_err}")
endif()
check_index("${WORK}/elsewhere/rel/asm/clouds/index.csv")
check_index("${WORK}/asm/clouds/index.csv")

# A rerun into the same --out removes the earlier run's clouds instead of mixing them.
file(WRITE "${WORK}/elsewhere/rel/asm/clouds/000999.pcd" "stale")
execute_process(COMMAND "${APP}" assemble "${WORK}/s.rawlog" --out rel/asm WORKING_DIRECTORY "${WORK}/elsewhere"
                RESULT_VARIABLE rerun_rc OUTPUT_QUIET ERROR_QUIET)
if(NOT rerun_rc EQUAL 0 OR EXISTS "${WORK}/elsewhere/rel/asm/clouds/000999.pcd")
  message(FATAL_ERROR "a rerun should succeed (${rerun_rc}) and remove the stale 000999.pcd")
endif()

# Ctrl-C after the second cloud: exit 130, the two complete clouds indexed, no more, and
# a message that says what is complete.
execute_process(COMMAND ${CMAKE_COMMAND} -E env RGBDT_TEST_INTERRUPT_AFTER_CLOUDS=2
                        "${APP}" assemble "${WORK}/s.rawlog" --out "${WORK}/asm_int"
                RESULT_VARIABLE int_rc OUTPUT_VARIABLE int_out ERROR_VARIABLE int_err)
file(GLOB int_pcds "${WORK}/asm_int/clouds/*.pcd")
list(LENGTH int_pcds n_int)
if(NOT int_rc EQUAL 130 OR NOT n_int EQUAL 2 OR NOT int_err MATCHES "interrupted: 2 complete tilt clouds")
  message(FATAL_ERROR "interrupted assemble: expected exit 130 and 2 clouds, got ${int_rc}, ${n_int}:\n${int_out}\n${int_err}")
endif()
file(STRINGS "${WORK}/asm_int/clouds/index.csv" int_rows)
list(LENGTH int_rows n_int_rows)
if(NOT n_int_rows EQUAL 3)
  message(FATAL_ERROR "interrupted assemble: index.csv should list the 2 complete clouds:\n${int_rows}")
endif()
check_index("${WORK}/asm_int/clouds/index.csv")

# A gzip file of garbage is not a rawlog: an error naming the file, not 0 observations.
string(RANDOM LENGTH 4000 garbage)
file(WRITE "${WORK}/garbage.txt" "${garbage}")
execute_process(COMMAND gzip -c "${WORK}/garbage.txt" OUTPUT_FILE "${WORK}/garbage.rawlog")
run_step(garbage "${APP}" info "${WORK}/garbage.rawlog")
if(garbage_rc EQUAL 0 OR NOT garbage_rc LESS 128 OR NOT garbage_err MATCHES "garbage\\.rawlog.*not an MRPT rawlog")
  message(FATAL_ERROR "info on gzip garbage should fail naming the file (${garbage_rc}):\n${garbage_out}\n${garbage_err}")
endif()

# Without the rig file the message names the file it looked for.
file(RENAME "${WORK}/s.tilt_rig.yaml" "${WORK}/moved.yaml")
run_step(norig "${APP}" assemble "${WORK}/s.rawlog" --out "${WORK}/asm2")
if(norig_rc EQUAL 0 OR NOT norig_err MATCHES "s\\.tilt_rig\\.yaml")
  message(FATAL_ERROR "assemble without a rig should fail naming s.tilt_rig.yaml (${norig_rc}):\n${norig_err}")
endif()
# The rig as `rgbdt_sim mapping` names it (tilt_rig.yaml beside the rawlog) is found and named.
file(RENAME "${WORK}/moved.yaml" "${WORK}/tilt_rig.yaml")
run_step(simrig "${APP}" assemble "${WORK}/s.rawlog" --out "${WORK}/asm3")
if(NOT simrig_rc EQUAL 0 OR NOT simrig_out MATCHES "rig: [^\n]*/tilt_rig\\.yaml")
  message(FATAL_ERROR "assemble should use tilt_rig.yaml beside the rawlog (${simrig_rc}):\n${simrig_out}\n${simrig_err}")
endif()
message(STATUS "rgbdt_tilt_lidar: ${scans} scans, ${encoder} encoder samples, ${n_pcd} tilts")
