#!/usr/bin/env bash
# Builds the core and kernels layers and their unit tests for aarch64 with Debian's cross
# compiler, the flags of the host build's compile_commands.json (Highway builds the NEON
# target of each dispatched file), and runs them under qemu's user-mode emulator. Then runs
# the digest of the kernels' outputs (Simd.SameBitsOnAnyThreadCount) natively too: the
# NEON bits must be the host's, which the host test checks against its baseline.
# Not part of scripts/test.sh: the emulated kernel tests take about 11 minutes on 2 cores,
# and the Arm libraries are extra packages.
#   scripts/test-aarch64.sh [BUILD_DIR]     (default build/, configured by scripts/build.sh)
# Needs: g++-aarch64-linux-gnu qemu-user-static, and with `dpkg --add-architecture arm64`:
#   libc6:arm64 libstdc++6:arm64 libopencv-core-dev:arm64 libhwy-dev:arm64
#   libgtest-dev:arm64 libgmock-dev:arm64 libimath-dev:arm64
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
for tool in aarch64-linux-gnu-g++ qemu-aarch64-static; do
  command -v "$tool" >/dev/null || { echo "test-aarch64: needs $tool (see the top of this script)" >&2; exit 2; }
done
for lib in libopencv_core.so libhwy.so libImath.so libgtest.a; do
  [ -e "/usr/lib/aarch64-linux-gnu/$lib" ] || { echo "test-aarch64: no arm64 $lib (see the top of this script)" >&2; exit 2; }
done
[ -f "$build_dir/compile_commands.json" ] || { echo "test-aarch64: no $build_dir/compile_commands.json" >&2; exit 2; }
[ -x "$build_dir/tests/ssdo_kernels_tests" ] || { echo "test-aarch64: build ssdo_kernels_tests first" >&2; exit 2; }

out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
echo -n "test-aarch64: "
python3 scripts/aarch64_compile.py "$build_dir/compile_commands.json" "$out" \
  core kernels tests/support tests/unit/kernels tests/unit/core

common=$(ls "$out"/*.o | grep -E '_core_|_kernels_|_tests_support_' | grep -v '_tests_unit_')
link() {  # link NAME TEST_OBJECTS...
  local name="$1"; shift
  aarch64-linux-gnu-g++ -o "$out/$name" "$@" $common -lopencv_core -lhwy -lImath -lgtest -lgtest_main -lpthread
}
link ssdo_kernels_tests $(ls "$out"/*_tests_unit_kernels_*.o)
link ssdo_core_tests $(ls "$out"/*_tests_unit_core_*.o)
echo "test-aarch64: linked; running under qemu-aarch64 (NEON)"
for t in ssdo_core_tests ssdo_kernels_tests; do
  qemu-aarch64-static "$out/$t" --gtest_brief=1 | tail -3
done
# The host's bits against the Arm build's.
digest() { "$@" --gtest_filter='Simd.SameBitsOnAnyThreadCount' 2>&1 | grep '^digest' || true; }
host=$(digest "$build_dir/tests/ssdo_kernels_tests")
arm=$(digest qemu-aarch64-static "$out/ssdo_kernels_tests")
echo "host ($(uname -m)): $host"
echo "arm (aarch64 NEON): $arm"
if [ -z "$host" ] || [ "$host" != "$arm" ]; then
  echo "test-aarch64: the Arm build's bits differ from the host's" >&2
  exit 1
fi
echo "test-aarch64: the same bits"
