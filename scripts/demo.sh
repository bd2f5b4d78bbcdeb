#!/usr/bin/env bash
# First command of the README: installs what is missing, builds, and runs the main job
# (AO + SSDO + composite) on the bundled example frames in examples/. Builds only what the
# demo runs: the ssdo executable and its OpenImageIO module (a dependency of the target);
# scripts/test.sh builds the tests and benchmarks.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target ssdo
exec examples/run.sh
