#!/usr/bin/env bash
# Frame I/O benchmark (figures, not a test): the wall time of `ssdo process` on the 1080p
# Cycles dump with AO and SSDO written, against `oiiotool` merely copying the channels
# ssdo reads (depth, normal, albedo) to half ZIP. Runs both alternately RUNS times and
# prints the medians and their ratio; then the throughput over a folder of 8 copies.
#
#   tests/bench/io_vs_oiiotool.sh [FRAME] [RUNS]
#   SSDO=build/ssdo  SSDO_ARGS="--preset medium"  to override
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
frame="${1:-$here/../shared/gbuffers/perf1080.exr}"
runs="${2:-5}"
ssdo="${SSDO:-$here/build/ssdo}"
ssdo_args=(${SSDO_ARGS:---terms ao,ssdo --method gtao --preset medium --env "$here/examples/env_equirect.exr"})
command -v oiiotool >/dev/null || { echo "oiiotool not found (apt-get install openimageio-tools)"; exit 1; }
[ -x "$ssdo" ] || { echo "no ssdo binary at $ssdo (scripts/build.sh)"; exit 1; }
[ -f "$frame" ] || { echo "no frame at $frame"; exit 1; }

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
stem="$(basename "$frame" .exr)"
cp "$frame" "$work/$stem.exr"
sidecar="${frame%.exr}.camera.json"
[ -f "$sidecar" ] && cp "$sidecar" "$work/$stem.camera.json"

# The channels ssdo reads, in oiiotool's --ch syntax, from the frame's own channel list.
layer="$(oiiotool --info -v "$frame" | sed -n 's/.*channel list: //p' | tr ',' '\n' | sed 's/ (.*//; s/^ *//' |
         grep -E '\.(Depth\.Z|Normal\.[XYZ]|DiffCol\.[RGB])$' | paste -sd, -)"

now() { date +%s.%N; }
calc() { awk "BEGIN { print $* }"; }
median() { sort -g | awk '{a[NR]=$1} END {print (NR%2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }

: >"$work/oiio.txt"; : >"$work/ssdo.txt"
for i in $(seq "$runs"); do
  t0=$(now); oiiotool "$work/$stem.exr" --ch "$layer" -d half --compression zip -o "$work/copy.exr"; t1=$(now)
  calc "$t1 - $t0" >>"$work/oiio.txt"
  t0=$(now); "$ssdo" process "$work/$stem.exr" -o "$work/out" --force "${ssdo_args[@]}" >/dev/null; t1=$(now)
  calc "$t1 - $t0" >>"$work/ssdo.txt"
done
m_oiio=$(median <"$work/oiio.txt"); m_ssdo=$(median <"$work/ssdo.txt")
printf 'oiiotool channel copy   median %.3f s over %d runs\n' "$m_oiio" "$runs"
printf 'ssdo process (%s) median %.3f s\n' "${ssdo_args[*]}" "$m_ssdo"
printf 'ratio ssdo / oiiotool   %.2f\n' "$(calc "$m_ssdo / $m_oiio")"
"$ssdo" process "$work/$stem.exr" -o "$work/out" --force -v "${ssdo_args[@]}" | grep -E 'read|compute' || true

mkdir -p "$work/eight"
for i in 1 2 3 4 5 6 7 8; do
  ln -f "$work/$stem.exr" "$work/eight/f$i.exr" 2>/dev/null || cp "$work/$stem.exr" "$work/eight/f$i.exr"
  [ -f "$work/$stem.camera.json" ] && cp "$work/$stem.camera.json" "$work/eight/f$i.camera.json"
done
t0=$(now); "$ssdo" process "$work/eight" -o "$work/out8" --force "${ssdo_args[@]}" >/dev/null; t1=$(now)
printf '8 frames: %.2f s, %.2f frames/s\n' "$(calc "$t1 - $t0")" "$(calc "8 / ($t1 - $t0)")"
