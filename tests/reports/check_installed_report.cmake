# Installs the build into PREFIX, runs PREFIX/bin/touchstone collision CONFIG --out OUT with
# TOUCHSTONE_REPORTS_DIR unset, and checks that report.md and the plots were written from the
# installed package (its folder is the first one the launcher tries, before the source tree).
file(REMOVE_RECURSE ${PREFIX} ${OUT})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX} RESULT_VARIABLE status OUTPUT_QUIET)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "cmake --install ${BUILD_DIR} --prefix ${PREFIX} failed: ${status}")
endif()
foreach(file bin/touchstone share/touchstone/reports/touchstone_reports/__main__.py
        share/touchstone/reports/schema/collision_results.schema.json)
  if(NOT EXISTS ${PREFIX}/${file})
    message(FATAL_ERROR "not installed: ${PREFIX}/${file}")
  endif()
endforeach()
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=TOUCHSTONE_REPORTS_DIR
                  ${PREFIX}/bin/touchstone collision ${CONFIG} --out ${OUT}
                RESULT_VARIABLE status OUTPUT_VARIABLE output ERROR_VARIABLE error)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "installed touchstone collision failed (${status}):\n${output}\n${error}")
endif()
foreach(file results.json report.md table1_overlap_tests.png tremor_error.png cycle_cost.png)
  if(NOT EXISTS ${OUT}/${file})
    message(FATAL_ERROR "the installed run did not write ${OUT}/${file}:\n${output}\n${error}")
  endif()
endforeach()
file(READ ${OUT}/report.md report)
if(NOT report MATCHES "Table 1 replica" OR report MATCHES "No plots")
  message(FATAL_ERROR "unexpected report.md:\n${report}")
endif()
message(STATUS "installed run wrote ${OUT}/report.md with plots")
