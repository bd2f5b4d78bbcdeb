#!/usr/bin/env bash
# Configures and builds ssdo (Release) into BUILD_DIR (default: build/).
#   scripts/build.sh                       everything: ssdo, its OpenImageIO module, tests, benchmarks
#   scripts/build.sh --target ssdo         only the executable and what it loads (the demo's build)
#   scripts/build.sh -DSSDO_WERROR=ON      any other argument goes to cmake's configure step
# --target NAME is repeatable; the targets are cmake's (ssdo, ssdo_integration_tests, ...).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-$(nproc)}
targets=()
configure=()
while [ $# -gt 0 ]; do
  case "$1" in
    --target)
      [ $# -ge 2 ] || { echo "scripts/build.sh: --target needs a target name" >&2; exit 2; }
      targets+=(--target "$2")
      shift 2
      ;;
    *)
      configure+=("$1")
      shift
      ;;
  esac
done
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release ${configure[@]+"${configure[@]}"} >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" ${targets[@]+"${targets[@]}"}
