# Builds the layer probes of layers.cmake: cmake -D BUILD_DIR=... -D GENERATOR=... -D POSITIVE=...
# -D NEGATIVE=... -P check_layers.cmake. POSITIVE: probes that must compile (a module includes
# what it may); NEGATIVE: "probe|header" pairs, each of which must fail because the header is not
# on the module's include path.
set(keep_going -k)
if(GENERATOR MATCHES "Ninja")
  set(keep_going -k 0)
endif()

execute_process(COMMAND ${CMAKE_COMMAND} --build ${BUILD_DIR} --target ${POSITIVE}
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${out}\nA module cannot include a module it links (probes above).")
endif()
list(LENGTH POSITIVE n)
message(STATUS "${n} modules include a header of each module they link")

set(targets "")
foreach(pair ${NEGATIVE})
  string(REPLACE "|" ";" pair "${pair}")
  list(GET pair 0 probe)
  list(APPEND targets ${probe})
endforeach()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${BUILD_DIR} --target ${targets} -- ${keep_going}
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
set(leaks "")
foreach(pair ${NEGATIVE})
  string(REPLACE "|" ";" pair "${pair}")
  list(GET pair 0 probe)
  list(GET pair 1 header)
  string(FIND "${out}" "${probe}.cpp:1:10: fatal error: ${header}: No such file or directory" at)
  if(at EQUAL -1)
    string(REGEX REPLACE "^layer_probe_(.*)_includes_(.*)$" "\\1 can include \\2/" leak ${probe})
    string(APPEND leaks "  ${leak} (${probe})\n")
  endif()
endforeach()
if(rc EQUAL 0 OR leaks)
  message(FATAL_ERROR "${out}\nUpward or sideways includes that did not fail as they must:\n${leaks}")
endif()
list(LENGTH NEGATIVE n)
message(STATUS "${n} includes of modules a module does not link fail to build, as they must")
