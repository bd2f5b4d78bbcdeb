#!/usr/bin/env bash
# Second command of the README (and CI's): installs what is missing, builds, and runs
# the whole test suite with CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
# Only what CTest runs (target ssdo_tests: no benchmarks), test programs and the service and
# formats libraries in unity batches, precompiled headers for the service library
# (cmake/build_speed.cmake).
scripts/build.sh -DSSDO_UNITY_TESTS=ON -DSSDO_UNITY_LIBRARIES=ON -DSSDO_PRECOMPILE_HEADERS=ON --target ssdo_tests
# One test more than cores (TEST_JOBS): a share of the tests wait on what they drive (child
# processes, sockets, the watcher's rescans, the Slurm scheduler), and the extra test keeps
# the cores busy meanwhile (measured: docs/fuzzing.md).
test_jobs=${TEST_JOBS:-$(($(nproc) + 1))}
(cd "${BUILD_DIR:-build}" && ctest --output-on-failure -j "$test_jobs" "$@")

# Second stage, on by default (CI runs it; SSDO_SANITIZE=0 leaves it out): the suite built
# by clang with AddressSanitizer + UndefinedBehaviorSanitizer (CMakePresets.json "asan",
# build-asan/: -O0 with line tables, the kernels -O3, no benchmarks, no accuracy suites, unity batches as
# above), run with `ctest --preset asan`, which also runs every fuzz target for
# SSDO_FUZZ_SECONDS (8 s) on its corpus (label fuzz; they run only in this clang build).
# Not under sanitizers: the Slurm cluster test (label slurm: it exercises the job scheduler,
# not our code), the whole-frame accuracy suites (label accuracy: minutes each under ASan,
# and the code paths they run are the unit tests'), and the tests that skip themselves in a
# sanitizer build, saying why: kernel tests that measure estimators or filters against
# brute-force references with large sample counts (SSDO_REFERENCE_MEASUREMENT: the same
# kernel code runs in the other kernel tests; tests/support/skips.h), and
# integration tests (SSDO_SKIP_IN_SANITIZER_BUILD: the confidence's error table over the shared
# frames, the tests that compute a whole shot twice to compare the bytes of two ways, and
# `ssdo bench` through the binary over every preset up to ultra).
# docs/fuzzing.md.
# The sanitizer build compiles the kernels for one instruction set, the build host's (AVX2
# where it runs it: CMakePresets.json, SSDO_SIMD_TARGETS host); the main stage runs the
# fallback of CPUs without AVX2 (KernelsOnTheBaselineInstructionSet, and simd_test holds it
# to the same bits). The four stages' times, measured: docs/fuzzing.md.
if [ "${SSDO_SANITIZE:-1}" != 0 ]; then
  cmake --preset asan >/dev/null
  cmake --build build-asan -j "${JOBS:-$(nproc)}"
  ctest --preset asan -j "$test_jobs" "$@"
fi
