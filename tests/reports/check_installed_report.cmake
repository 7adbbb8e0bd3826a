# Installs the build into PREFIX, runs PREFIX/bin/touchstone collision CONFIG --out OUT with
# TOUCHSTONE_REPORTS_DIR unset, and checks that report.md and the plots were written from the
# installed package (its folder is the first one the launcher tries, before the source tree).
# Then again with a matplotlib that fails to import: report.md is still written, without plots,
# and says why.
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

set(fake ${OUT}_fake_matplotlib)
file(REMOVE_RECURSE ${fake} ${OUT}_no_matplotlib)
file(WRITE ${fake}/matplotlib/__init__.py "raise ImportError('no matplotlib here')\n")
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=TOUCHSTONE_REPORTS_DIR PYTHONPATH=${fake}
                  ${PREFIX}/bin/touchstone collision ${CONFIG} --out ${OUT}_no_matplotlib
                RESULT_VARIABLE status OUTPUT_VARIABLE output ERROR_VARIABLE error)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "touchstone collision without matplotlib failed (${status}):\n${output}\n${error}")
endif()
file(READ ${OUT}_no_matplotlib/report.md report)
if(NOT report MATCHES "No plots: the plot step failed" OR EXISTS ${OUT}_no_matplotlib/cycle_cost.png)
  message(FATAL_ERROR "without matplotlib: unexpected report.md:\n${report}")
endif()
# The failed attempt names the package folder it ran: the installed one.
string(FIND "${report}" "(PYTHONPATH ${PREFIX}/share/touchstone/reports)" installed)
if(installed EQUAL -1)
  message(FATAL_ERROR "the report was not run from ${PREFIX}/share/touchstone/reports:\n${report}")
endif()
if(NOT error MATCHES "matplotlib is missing")
  message(FATAL_ERROR "without matplotlib: the reason was not printed:\n${error}")
endif()
message(STATUS "without matplotlib: report.md without plots, saying why")
