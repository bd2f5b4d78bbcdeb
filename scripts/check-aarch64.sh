#!/usr/bin/env bash
# Compiles every source of the core, kernels, formats and service layers for aarch64 with
# Debian's cross compiler (g++-aarch64-linux-gnu), the flags of the host build's
# compile_commands.json: Highway then builds the NEON target of each dispatched file. A
# compile check, not a link (the Arm libraries are not installed) nor a run.
#   scripts/check-aarch64.sh [BUILD_DIR]     (default build/, configured by scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
if ! command -v aarch64-linux-gnu-g++ >/dev/null; then
  echo "check-aarch64: needs aarch64-linux-gnu-g++ (apt-get install g++-aarch64-linux-gnu)" >&2
  exit 2
fi
if [ ! -f "$build_dir/compile_commands.json" ]; then
  echo "check-aarch64: no $build_dir/compile_commands.json (configure with scripts/build.sh first)" >&2
  exit 2
fi
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
echo -n "check-aarch64: "
python3 scripts/aarch64_compile.py "$build_dir/compile_commands.json" "$out" core kernels formats service
