#!/usr/bin/env bash
# End-to-end benchmark of `ssdo process` on a folder of 1080p frames (figures, not a test):
# per-stage times (read, compute, write: medians over the frames, as `ssdo process -v`
# reports them), the batch's wall time against its I/O floor (the same batch with
# --io-only: the same channels read and the same channels written, nothing computed), and
# the peak resident memory of the worker (its getrusage, which `ssdo process -v` prints
# with each frame) against the decoded G-buffer (the channels read, as float).
# The full batch and the floor run alternately RUNS times in one run.
#
#   tests/bench/end_to_end.sh [FRAME] [FRAMES] [RUNS]
#   SSDO=build/ssdo  SSDO_ARGS="--terms ao,ssdo --preset low ..."  to override
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
frame="${1:-$here/../shared/gbuffers/perf1080.exr}"
count="${2:-8}"
runs="${3:-1}"
ssdo="${SSDO:-$here/build/ssdo}"
ssdo_args=(${SSDO_ARGS:---terms ao,ssdo --method gtao --preset low --ssdo-preset low --compression none --env "$here/examples/env_equirect.exr"})
[ -x "$ssdo" ] || { echo "no ssdo binary at $ssdo (scripts/build.sh)"; exit 1; }
[ -f "$frame" ] || { echo "no frame at $frame"; exit 1; }
[ -x /usr/bin/time ] || { echo "/usr/bin/time not found (apt-get install time)"; exit 1; }

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
stem="$(basename "$frame" .exr)"
mkdir -p "$work/in"
sidecar="${frame%.exr}.camera.json"
for i in $(seq "$count"); do
  cp "$frame" "$work/in/f$i.exr"  # copies, not links: each frame is read from its own file
  [ -f "$sidecar" ] && cp "$sidecar" "$work/in/f$i.camera.json"
done

# shellcheck source=tests/bench/bench_lib.sh
source "$here/tests/bench/bench_lib.sh"  # median, stage

echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "ssdo settings: ${ssdo_args[*]}"
for mode in full floor; do : >"$work/$mode.wall"; : >"$work/$mode.log"; : >"$work/$mode.rss"; done
for r in $(seq "$runs"); do
  for mode in full floor; do
    extra=(); [ "$mode" = floor ] && extra=(--io-only)
    t0=$(date +%s.%N)
    "$ssdo" process "$work/in" -o "$work/out-$mode" --force -v "${ssdo_args[@]}" "${extra[@]}" >"$work/run.log"
    t1=$(date +%s.%N)
    cat "$work/run.log" >>"$work/$mode.log"
    awk "BEGIN { print $t1 - $t0 }" >>"$work/$mode.wall"
    # KiB, as /usr/bin/time's %M: the largest of the run's workers.
    sed -n 's/.* worker peak RSS \([0-9.]*\) MiB.*/\1/p' "$work/run.log" | sort -g | tail -1 |
      awk '{ print $1 * 1024 }' >>"$work/$mode.rss"
  done
done

# The decoded G-buffer: the channels the worker reads (`ssdo info` lists them), as float.
channels=$("$ssdo" info "$work/in/f1.exr" --json 2>/dev/null |
  python3 -c 'import json,sys; d=json.load(sys.stdin); d=d[0] if isinstance(d,list) else d; print(d["width"]*d["height"])' 2>/dev/null || echo 0)
for mode in full floor; do
  wall=$(median <"$work/$mode.wall")
  printf '%-6s %d frames: %.2f s (median of %d), %.3f frames/s; per frame read %.0f, compute %.0f, write %.0f ms; peak RSS %.0f MiB\n' \
    "$mode" "$count" "$wall" "$runs" "$(awk "BEGIN{print $count / $wall}")" \
    "$(stage read <"$work/$mode.log" | median)" "$(stage compute <"$work/$mode.log" | median)" \
    "$(stage write <"$work/$mode.log" | median)" "$(awk "BEGIN{print $(median <"$work/$mode.rss") / 1024}")"
done
full=$(median <"$work/full.wall"); floor=$(median <"$work/floor.wall")
printf 'end to end / I/O floor: %.2f\n' "$(awk "BEGIN{print $full / $floor}")"
if [ "$channels" != 0 ]; then
  # depth 1 + normal 3 + albedo 3 + lighting 3 floats, plus the mask byte (see ssdo info's "uses").
  mib=$(awk "BEGIN{print $channels * (10 * 4 + 1) / 1048576}")
  printf 'decoded G-buffer (depth, normal, albedo, lighting as float + mask): %.0f MiB; peak RSS / G-buffer: full %.2f, floor %.2f\n' \
    "$mib" "$(awk "BEGIN{print $(median <"$work/full.rss") / 1024 / $mib}")" "$(awk "BEGIN{print $(median <"$work/floor.rss") / 1024 / $mib}")"
fi
echo "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"
