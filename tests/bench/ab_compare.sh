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
awk '
  function median(list,    n, v, i, j, t) {
    n = split(list, v, " ")
    for (i = 2; i <= n; ++i) for (j = i; j > 1 && v[j - 1] + 0 > v[j] + 0; --j) { t = v[j]; v[j] = v[j - 1]; v[j - 1] = t }
    return n % 2 ? v[(n + 1) / 2] : (v[n / 2] + v[n / 2 + 1]) / 2
  }
  { key = $3; time[$1, $2, key] = $4; all[$1, key] = all[$1, key] " " $4; names[key] = 1
    if (!(($1, key) in low) || $4 + 0 < low[$1, key]) low[$1, key] = $4 + 0 }
  END {
    for (key in names) {
      ratios = ""
      for (k in time) { split(k, f, SUBSEP); if (f[1] == "A" && f[3] == key && (("B", f[2], key) in time))
        ratios = ratios " " time["B", f[2], key] / time["A", f[2], key] }
      printf "%-44s %8.4g / %-8.4g %8.4g / %-8.4g %12.3f\n", key, low["A", key], low["B", key],
             median(all["A", key]), median(all["B", key]), median(ratios)
    }
  }' "$runs" | sort
