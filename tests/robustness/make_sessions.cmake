# Writes the pristine sessions the robustness cases copy and break:
#   cmake -DBIN=<build>/bin -DOUT=<folder> -P make_sessions.cmake
file(REMOVE_RECURSE ${OUT})
execute_process(COMMAND ${BIN}/rgbdt_sim calibration --out ${OUT}/cal --views 2 --supersampling 1 -q
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "rgbdt_sim calibration failed (${rc})")
endif()
execute_process(COMMAND ${BIN}/rgbdt_sim mapping --out ${OUT}/map --duration 3 --rgb-fps 2
                        --thermal-fps 5 --supersampling 1 -q
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "rgbdt_sim mapping failed (${rc})")
endif()
