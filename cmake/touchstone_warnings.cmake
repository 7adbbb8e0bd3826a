# One warning policy for every target of the project: -Wall -Wextra, and -Werror when
# TOUCHSTONE_WARNINGS_AS_ERRORS is on (the CI build), so that a new warning fails CI instead of
# scrolling past.
option(TOUCHSTONE_WARNINGS_AS_ERRORS "Treat compiler warnings as errors" OFF)

function(touchstone_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra $<$<BOOL:${TOUCHSTONE_WARNINGS_AS_ERRORS}>:-Werror>)
endfunction()
