#!/usr/bin/env bash
# The product's sources read without side scrolling: no line longer than MAX_COLUMNS
# characters in core/, kernels/, formats/ and service/. Lists the offenders and fails when
# there are any.
# Usage: line_length.sh SOURCE_DIR [MAX_COLUMNS]
set -euo pipefail
# shellcheck source=tests/structure/report.sh
source "$(dirname "$0")/report.sh"  # layer_sources, report
src=${1:?source dir}
max=${2:-120}
cd "$src"
layer_sources core kernels formats service
long=$(awk -v n="$max" 'length($0) > n { printf "%4d columns  %s:%d\n", length($0), FILENAME, FNR }' "${files[@]}")
report "$long" "lines over $max columns in $layer_names" \
  "no line over $max columns in ${#files[@]} files of $layer_names"
