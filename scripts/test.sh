#!/usr/bin/env bash
# Second command of the README (and CI's): installs what is missing, builds, and runs
# the whole test suite with CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
(cd "${BUILD_DIR:-build}" && ctest --output-on-failure -j "${JOBS:-$(nproc)}" "$@")

# Second stage: the same suite built by clang with AddressSanitizer + UndefinedBehavior-
# Sanitizer (CMakePresets.json "asan", in build-asan/), plus a short run of every fuzz
# target (label fuzz). Not under sanitizers: the Slurm cluster test (label slurm: it
# exercises the job scheduler, not our code) and the heavy accuracy suites on whole frames
# (label accuracy, and by name FailureCases, Accuracy, SsdoOnSharedFrames, SsdoOnGreeble,
# ConfidenceIntegration:
# 2 to 4 minutes each under ASan; the same code paths run in the unit tests).
# The stage doubles the build and more than doubles the test time on 2 cores, so it runs
# when asked: SSDO_SANITIZE=1 scripts/test.sh. README.md, "Fuzzing and sanitizers".
if [ "${SSDO_SANITIZE:-0}" != 0 ]; then
  cmake --preset asan >/dev/null
  cmake --build build-asan -j "${JOBS:-$(nproc)}"
  (cd build-asan && ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1} UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1} \
    ctest --output-on-failure -j "${JOBS:-$(nproc)}" -LE "^(slurm|accuracy)$" \
      -E "^(FailureCases|Accuracy|SsdoOnSharedFrames|SsdoOnGreeble|ConfidenceIntegration)\." "$@")
fi
