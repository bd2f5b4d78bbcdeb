# Script mode (run after a test program is linked; tests/CMakeLists.txt, ssdo_test_program's
# PER_SUITE): writes OUTPUT, a CTest file registering one test per GoogleTest suite of
# PROGRAM, named "<Suite>.*" and running --gtest_filter=<Suite>.*, instead of one process
# per test. For programs whose process start is most of a short test's time: a program
# that links OpenImageIO loads about 260 libraries, every symbol bound at load (BIND_NOW),
# 0.4 s per process (0.7 s under ASan) before its first test.
#   cmake -D PROGRAM=<file> -D OUTPUT=<file> -D LABEL=<label> -D COST_PER_TEST=<n>
#         -D TIMEOUT=<seconds> -P gtest_suites.cmake
# The cost of a suite is COST_PER_TEST times its tests, so that CTest starts the largest
# suites first on a clean clone (no timings of earlier runs).
foreach(var PROGRAM OUTPUT LABEL COST_PER_TEST TIMEOUT)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "gtest_suites.cmake: -D ${var}=... is required")
  endif()
endforeach()

execute_process(COMMAND "${PROGRAM}" --gtest_list_tests
                OUTPUT_VARIABLE listing ERROR_VARIABLE errors RESULT_VARIABLE result TIMEOUT 60)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "gtest_suites.cmake: ${PROGRAM} --gtest_list_tests failed (${result}):\n${listing}${errors}")
endif()

# The listing: a suite per line ("Suite." or "Prefix/Suite.", typed suites followed by a
# comment), then its tests indented by two spaces. gtest_main's banner matches neither.
string(REPLACE "\n" ";" lines "${listing}")
set(suites "")
set(suite "")
foreach(line IN LISTS lines)
  if(line MATCHES "^([A-Za-z0-9_/]+)\\.( |$)")
    set(suite "${CMAKE_MATCH_1}")
    list(APPEND suites "${suite}")
    string(MAKE_C_IDENTIFIER "${suite}" id)
    set(tests_${id} 0)
  elseif(suite AND line MATCHES "^  [A-Za-z0-9_/]")
    math(EXPR tests_${id} "${tests_${id}} + 1")
  endif()
endforeach()
if(NOT suites)
  message(FATAL_ERROR "gtest_suites.cmake: no test suite in the listing of ${PROGRAM}:\n${listing}")
endif()

set(content "# Written by cmake/gtest_suites.cmake from ${PROGRAM} --gtest_list_tests.\n")
foreach(suite IN LISTS suites)
  string(MAKE_C_IDENTIFIER "${suite}" id)
  math(EXPR cost "${COST_PER_TEST} * ${tests_${id}}")
  string(APPEND content
    "add_test([=[${suite}.*]=] [=[${PROGRAM}]=] [=[--gtest_filter=${suite}.*]=])\n"
    "set_tests_properties([=[${suite}.*]=] PROPERTIES LABELS [=[${LABEL}]=] TIMEOUT ${TIMEOUT} COST ${cost})\n")
endforeach()
file(WRITE "${OUTPUT}" "${content}")
