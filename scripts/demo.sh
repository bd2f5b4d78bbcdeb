#!/usr/bin/env bash
# First command of the README: installs what is missing, builds, and runs the main job
# (AO + SSDO + composite) on the bundled example frames in examples/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
exec examples/run.sh
