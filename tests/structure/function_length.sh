#!/usr/bin/env bash
# The product's layers read as small functions: no function (a lambda counts with its
# enclosing function and on its own) longer than MAX_LINES lines in core/, kernels/ and
# formats/. Lists the offenders and fails when there are any; skips (77) without ctags.
# Usage: function_length.sh SOURCE_DIR [MAX_LINES]
set -euo pipefail
# shellcheck source=tests/structure/report.sh
source "$(dirname "$0")/report.sh"  # layer_sources, report
src=${1:?source dir}
max=${2:-80}
if ! ctags --version 2>/dev/null | grep -q 'Universal Ctags'; then
  echo "skipped: Universal Ctags is not installed (scripts/install-deps.sh installs it)"
  exit 77
fi
cd "$src"
layer_sources core kernels formats
long=$(ctags --c++-kinds=f --fields=+ne --extras=-q -f - "${files[@]}" | awk -F'\t' -v n="$max" '{
  start = ""; end = ""
  for (i = 4; i <= NF; i++) { if ($i ~ /^line:/) start = substr($i, 6); if ($i ~ /^end:/) end = substr($i, 5) }
  if (start != "" && end != "" && end - start + 1 > n) printf "%5d lines  %s:%s  %s\n", end - start + 1, $2, start, $1
}' | sort -rn)
report "$long" "functions over $max lines in $layer_names" \
  "no function over $max lines in ${#files[@]} files of $layer_names"
