#!/usr/bin/env bash
# Thread scaling of every kernel (figures, not a test): `ao_bench`'s timings of each kernel
# at 1920x1080 with 1 and with 2 threads, REPS repetitions of each in a random interleaved
# order (Google Benchmark's --benchmark_enable_random_interleaving), so that the two thread
# counts of a kernel share the machine's slow and fast phases instead of running minutes
# apart; prints per kernel the medians, their ratio (the scaling) and whether it reaches
# MIN_SCALING, and the ratio of the two thread counts' fastest runs (what each runs at when
# nothing else on the host slows it). On a shared 2-core machine one run of each moves the
# ratio by 0.3 either way, and series of 9 medians by 0.25: take 15 or more.
#
#   tests/bench/thread_scaling.sh [REPS] [FILTER]
#   AO_BENCH=build/tests/bench/ao_bench  MIN_SCALING=1.8  to override
#
# FILTER (a regex over the benchmark names, without the thread count; default: the AO
# methods and SSDO at low and medium, the whole frame, the denoisers, the confidence,
# the box blur, the temporal filter and a shot frame's finish, all at 1920).
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
reps="${1:-7}"
filter="${2:-^(BM_Ao/1920/[0-2]/[01]|BM_Ssdo/1920/[01]|BM_Frame/1920/[01]|BM_Denoise/1920|BM_Denoise3/1920|BM_DenoiseHalfGridTerms/1920/[12]|BM_Confidence/1920|BM_BoxBlur/1920|BM_Temporal/1920/[12]|BM_ShotFinish/1920/2/[01])}"
bench="${AO_BENCH:-$here/build/tests/bench/ao_bench}"
min_scaling="${MIN_SCALING:-1.8}"
[[ "$reps" =~ ^[0-9]+$ && "$reps" -ge 2 ]] || { echo "REPS must be a whole number >= 2 (medians need repetitions), not '$reps'"; exit 1; }
[ -x "$bench" ] || { echo "no benchmark binary at $bench (scripts/build.sh builds it)"; exit 1; }

csv="$(mktemp)" log="$(mktemp)"
trap 'rm -f "$csv" "$log"' EXIT
# Thread counts are every benchmark's last argument. The CSV goes to stdout, the machine's
# description and any error to stderr (shown when nothing was measured).
"$bench" --benchmark_filter="$filter/[12]/real_time\$" --benchmark_repetitions="$reps" \
  --benchmark_enable_random_interleaving=true --benchmark_format=csv >"$csv" 2>"$log" || { cat "$log"; exit 1; }
grep -q '_median"' "$csv" || { cat "$log"; echo "no benchmark matched '$filter' with 1 and 2 threads"; exit 1; }

echo "ao_bench, 1920x1080, $reps interleaved runs each, ms ($(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo '?'), $(date -u +%Y-%m-%d))"
printf "%-34s %-24s %10s %10s %8s %10s\n" "benchmark" "what" "1 thread" "2 threads" "scaling" "fastest"
awk -F'"' -v min="$min_scaling" '
  # Rows: "name",iterations,real_time,cpu_time,time_unit,...,"label",...: one per run
  # ("name" ends in /real_time), then the aggregates ("/real_time_median" among them).
  /\/real_time(_median)?"/ {
    name = $2; median = sub("/real_time_median$", "", name); sub("/real_time$", "", name)
    threads = name; sub(".*/", "", threads)
    kernel = name; sub("/[0-9]+$", "", kernel)
    split($3, f, ","); ms = f[3] + 0
    if (!(kernel in seen)) { seen[kernel] = 1; order[n++] = kernel }
    if (median) {
      time[kernel, threads] = ms
    } else {
      if (!((kernel, threads) in fastest) || ms < fastest[kernel, threads]) fastest[kernel, threads] = ms
      label = $4; sub("(^|,? )[12]t$", "", label); label = substr(label, 1, 24)
      if (label != "") labels[kernel] = label
    }
  }
  END {
    below = 0
    for (i = 0; i < n; ++i) {
      k = order[i]; t1 = time[k, 1]; t2 = time[k, 2]
      if (t1 == "" || t2 == "") continue
      s = t1 / t2
      flag = s < min ? "  < " min : ""
      below += s < min
      printf "%-34s %-24s %10.1f %10.1f %7.2fx %9.2fx%s\n", k, labels[k], t1, t2, s, fastest[k, 1] / fastest[k, 2], flag | "sort"
    }
    close("sort")
    printf "%d of %d below %sx (medians)\n", below, n, min
  }' "$csv"
