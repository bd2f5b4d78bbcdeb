#!/usr/bin/env bash
# Two builds of a benchmark binary against each other (figures, not a test): PAIRS pairs of
# single runs of every benchmark FILTER selects, the two builds alternated (A then B, then B
# then A, ...) so that both share the machine's slow and fast phases; prints per benchmark
# each build's fastest and median run and the median of the pairs' ratios B / A. On a shared
# virtual machine a kernel's time moves by 30-40% between phases minutes apart (and a
# gather-bound one by 2x), so the medians of separate series mislead; the ratio within a pair
# does not, and the fastest runs show each build where nothing else slows it.
#
#   tests/bench/ab_compare.sh A_BINARY B_BINARY FILTER [PAIRS]
#
# e.g. with the build of the commit before a change copied aside:
#   cp build/tests/bench/ao_bench /tmp/ao_before   # at the commit before
#   tests/bench/ab_compare.sh /tmp/ao_before build/tests/bench/ao_bench 'BM_TemporalSsdo' 12
set -euo pipefail
# shellcheck source=tests/bench/bench_lib.sh
source "$(dirname "$0")/bench_lib.sh"  # median
[ $# -ge 3 ] || { sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 1; }
a="$1" b="$2" filter="$3" pairs="${4:-10}"
[[ "$pairs" =~ ^[0-9]+$ && "$pairs" -ge 1 ]] || { echo "PAIRS must be a whole number >= 1, not '$pairs'"; exit 1; }
for bin in "$a" "$b"; do [ -x "$bin" ] || { echo "no benchmark binary at $bin"; exit 1; }; done

runs="$(mktemp)" log="$(mktemp)"
trap 'rm -f "$runs" "$log"' EXIT
# One run of every selected benchmark by build $1 (tag $2, pair $3): "tag pair name ms" lines.
run() {
  "$1" --benchmark_filter="$filter" --benchmark_repetitions=1 --benchmark_format=csv 2>"$log" |
    awk -F, -v tag="$2" -v pair="$3" '$1 ~ /^"BM_/ { gsub("\"", "", $1); print tag, pair, $1, $3 }' >>"$runs" ||
    { cat "$log"; exit 1; }
}
for ((p = 1; p <= pairs; ++p)); do
  if ((p % 2)); then run "$a" A "$p"; run "$b" B "$p"; else run "$b" B "$p"; run "$a" A "$p"; fi
done
[ -s "$runs" ] || { cat "$log"; echo "no benchmark matched '$filter'"; exit 1; }

echo "A: $a"
echo "B: $b"
echo "$pairs alternated pairs of single runs, time as the benchmark reports it ($(date -u +%Y-%m-%d))"
printf "%-44s %17s %17s %12s\n" "benchmark" "fastest A / B" "median A / B" "median B/A"
awk '{ print $3 }' "$runs" | sort -u | while read -r key; do
  times() { awk -v tag="$1" -v key="$key" '$1 == tag && $3 == key { print $4 }' "$runs"; }
  # B / A within each pair that has both runs.
  ratios="$(awk -v key="$key" '$3 == key { t[$1, $2] = $4; pair[$2] = 1 }
    END { for (p in pair) if ((("A", p) in t) && (("B", p) in t)) print t["B", p] / t["A", p] }' "$runs")"
  printf "%-44s %8.4g / %-8.4g %8.4g / %-8.4g %12.3f\n" "$key" "$(times A | sort -g | head -1)" \
    "$(times B | sort -g | head -1)" "$(times A | median)" "$(times B | median)" "$(median <<<"$ratios")"
done
