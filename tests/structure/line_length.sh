#!/usr/bin/env bash
# The product's sources read without side scrolling: no line longer than MAX_COLUMNS
# characters in core/, kernels/, formats/ and service/. Lists the offenders and fails when
# there are any.
# Usage: line_length.sh SOURCE_DIR [MAX_COLUMNS]
set -euo pipefail
# shellcheck source=tests/structure/report.sh
source "$(dirname "$0")/report.sh"  # report
src=${1:?source dir}
max=${2:-120}
cd "$src"
shopt -s nullglob  # a pattern that matches nothing is left out, not passed on as a name
files=(core/*.{h,cpp} kernels/*.{h,cpp} formats/*.{h,cpp} formats/*/*.{h,cpp} service/*.{h,cpp})
long=$(awk -v n="$max" 'length($0) > n { printf "%4d columns  %s:%d\n", length($0), FILENAME, FNR }' "${files[@]}")
report "$long" "lines over $max columns in core/, kernels/, formats/ and service/" \
  "no line over $max columns in ${#files[@]} files of core/, kernels/, formats/ and service/"
