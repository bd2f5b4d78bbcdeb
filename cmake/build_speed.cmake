# Clean-build speed (CI builds from a fresh clone without a compiler cache; most of its
# compile time is the test programs).
#   SSDO_UNITY_TESTS         each test program compiles its sources in batches of
#                            SSDO_UNITY_BATCH files, one translation unit per batch: the
#                            GoogleTest, JSON and OpenCV templates every test file
#                            instantiates are compiled once per batch instead of once per
#                            file. For clean builds (scripts/test.sh turns it on): a batch
#                            recompiles whole when one of its files changes.
#   SSDO_UNITY_LIBRARIES     the same batches for ssdo_service and ssdo_formats (the
#                            kernels compile each file once per instruction set, which a
#                            batch cannot hold). scripts/test.sh and the asan preset turn it
#                            on; a build configured without it (scripts/build.sh's and the
#                            demo's, from a fresh clone) compiles every file alone, which is
#                            where a file that misses an include (hidden by an earlier file
#                            of its batch) shows.
#   SSDO_PRECOMPILE_HEADERS  ssdo_service (31 files, most of them including OpenCV core,
#                            GLM, nlohmann-json and CLI11) parses those headers once.
#                            Left out when a compiler launcher is set: ccache caches
#                            nothing that reads a precompiled header.
#   SSDO_TEST_OPTIMIZATION   the test programs' optimization flag in every build type
#                            (-O1): the code under test keeps its own flags (the
#                            libraries'), and -O3 on test files costs a third more compile
#                            time for assertions and fixtures that run once. The asan
#                            preset uses -O0: clang with the sanitizers compiles the test
#                            programs at -O0 in half the time of -O1. A program that
#                            computes references per pixel in its own code (the kernels'
#                            ray-cast scenes and closed forms) is built at -O1 at least: at
#                            -O0 under the sanitizers its tests took twice as long.
set(SSDO_TEST_OPTIMIZATION -O1 CACHE STRING "Optimization flag of the test programs (-O0, -O1, ...)")
option(SSDO_UNITY_TESTS "Compile each test program's sources in batches" OFF)
option(SSDO_UNITY_LIBRARIES "Compile ssdo_service's and ssdo_formats' sources in batches" OFF)
set(SSDO_UNITY_BATCH 8 CACHE STRING "Source files per unity batch")
option(SSDO_PRECOMPILE_HEADERS "Precompiled third-party headers for ssdo_service" OFF)
if(SSDO_PRECOMPILE_HEADERS AND CMAKE_CXX_COMPILER_LAUNCHER)
  message(STATUS "ssdo: precompiled headers off: the compiler launcher (${CMAKE_CXX_COMPILER_LAUNCHER}) cannot cache them")
  set(SSDO_PRECOMPILE_HEADERS OFF)
endif()

# ssdo_precompile(TARGET HEADER...): only third-party headers the target's sources already
# include (directly or through the project's headers), so that no layer gets a library
# its own code does not include.
function(ssdo_precompile target)
  if(SSDO_PRECOMPILE_HEADERS)
    list(TRANSFORM ARGN PREPEND "<")
    list(TRANSFORM ARGN APPEND ">")
    target_precompile_headers(${target} PRIVATE ${ARGN})
  endif()
endfunction()

# ssdo_test_build_flags(TARGET [COMPUTES_REFERENCES]): a test program's compile settings
# above; COMPUTES_REFERENCES raises -O0 to -O1.
function(ssdo_test_build_flags target)
  cmake_parse_arguments(PARSE_ARGV 1 arg "COMPUTES_REFERENCES" "" "")
  set(optimization ${SSDO_TEST_OPTIMIZATION})
  if(arg_COMPUTES_REFERENCES AND optimization STREQUAL "-O0")
    set(optimization -O1)
  endif()
  target_compile_options(${target} PRIVATE ${optimization})
  if(SSDO_UNITY_TESTS)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${SSDO_UNITY_BATCH})
  endif()
endfunction()

# ssdo_library_build_flags(TARGET): a library's batches (SSDO_UNITY_LIBRARIES above).
function(ssdo_library_build_flags target)
  if(SSDO_UNITY_LIBRARIES)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${SSDO_UNITY_BATCH})
  endif()
endfunction()
