#!/usr/bin/env bash
# Frame I/O benchmark (figures, not a test): the wall time of `ssdo process` on the 1080p
# Cycles dump with AO and SSDO written, against `oiiotool` merely copying the channels
# ssdo reads (depth, normal, albedo) to half ZIP. Runs every command alternately RUNS
# times in one run (ratios hold on a loaded machine) and prints the medians, the ratios to
# oiiotool and the per-stage split ssdo reports (read, compute, write: medians over the
# runs); then the throughput over a folder of 8 copies of the frame (frames/s: a batch's
# steady state, so once the earlier runs' outputs fill the page cache's dirty limit the
# uncompressed batches, 87 MB a frame, run at the disk's write speed). Every run
# writes new files, as a batch does: the outputs of the previous run are removed first
# (replacing a file costs more than writing one: on ext4, renaming over a file first
# flushes the new one, ~30 ms for 45 MB).
#
#   tests/bench/io_vs_oiiotool.sh [FRAME] [RUNS]
#   SSDO=build/ssdo  SSDO_ARGS="--terms ao,ssdo --preset low ..."  to override
#
# Commands timed (SSDO_ARGS = the speed settings: fastest presets):
#   oiiotool FRAME --ch <depth, normal, albedo> -d half --compression zip -o copy.exr
#   ssdo process FRAME SSDO_ARGS                         (default compression: zip level 1)
#   ssdo process FRAME SSDO_ARGS --compression none      (the fast lossless choice)
#   ssdo process FRAME SSDO_ARGS --compression none --io-only   (the same I/O, nothing computed)
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
frame="${1:-$here/../shared/gbuffers/perf1080.exr}"
runs="${2:-5}"
ssdo="${SSDO:-$here/build/ssdo}"
ssdo_args=(${SSDO_ARGS:---terms ao,ssdo --method gtao --preset low --ssdo-preset low --env "$here/examples/env_equirect.exr"})
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
# shellcheck source=tests/bench/bench_lib.sh
source "$here/tests/bench/bench_lib.sh"  # median, stage

configs=(zip none io)
config_args() {
  case "$1" in
    zip) echo "" ;;
    none) echo "--compression none" ;;
    io) echo "--compression none --io-only" ;;
  esac
}
config_name() {
  case "$1" in
    zip) echo "ssdo process (default zip)" ;;
    none) echo "ssdo process --compression none" ;;
    io) echo "ssdo process --compression none --io-only" ;;
  esac
}

echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
: >"$work/oiio.txt"
for c in "${configs[@]}"; do : >"$work/$c.txt"; : >"$work/$c.log"; done
for i in $(seq "$runs"); do
  rm -f "$work/copy.exr"
  t0=$(now); oiiotool "$work/$stem.exr" --ch "$layer" -d half --compression zip -o "$work/copy.exr"; t1=$(now)
  calc "$t1 - $t0" >>"$work/oiio.txt"
  for c in "${configs[@]}"; do
    rm -rf "$work/out-$c"
    t0=$(now)
    "$ssdo" process "$work/$stem.exr" -o "$work/out-$c" --force -v "${ssdo_args[@]}" $(config_args "$c") >>"$work/$c.log"
    t1=$(now)
    calc "$t1 - $t0" >>"$work/$c.txt"
  done
done
m_oiio=$(median <"$work/oiio.txt")
echo "ssdo settings: ${ssdo_args[*]}"
printf '%-44s median %7.3f s over %d runs\n' "oiiotool --ch (7 channels) -d half zip" "$m_oiio" "$runs"
for c in "${configs[@]}"; do
  m=$(median <"$work/$c.txt")
  printf '%-44s median %7.3f s  ratio to oiiotool %.2f  (read %.0f, compute %.0f, write %.0f ms; %s MB)\n' \
    "$(config_name "$c")" "$m" "$(calc "$m / $m_oiio")" \
    "$(stage read <"$work/$c.log" | median)" "$(stage compute <"$work/$c.log" | median)" \
    "$(stage write <"$work/$c.log" | median)" "$(calc "$(stat -c %s "$work/out-$c/$stem.ssdo.exr") / 1e6")"
done

# Named without frame numbers: eight independent frames, not a shot (a shot of eight equal
# frames would add the views and the temporal filter, whose every texel agrees).
mkdir -p "$work/eight"
for i in a b c d e f g h; do
  ln -f "$work/$stem.exr" "$work/eight/f$i.exr" 2>/dev/null || cp "$work/$stem.exr" "$work/eight/f$i.exr"
  [ -f "$work/$stem.camera.json" ] && cp "$work/$stem.camera.json" "$work/eight/f$i.camera.json"
done
for c in zip none io; do
  t0=$(now); "$ssdo" process "$work/eight" -o "$work/out8-$c" --force "${ssdo_args[@]}" $(config_args "$c") >/dev/null; t1=$(now)
  printf '8 frames, %-40s %.2f s, %.3f frames/s\n' "$(config_name "$c"):" "$(calc "$t1 - $t0")" "$(calc "8 / ($t1 - $t0)")"
done
# Two frames at once, one thread each: one frame's reading and writing overlap the other's
# computing (the stages of one frame run in order inside its worker).
t0=$(now); "$ssdo" process "$work/eight" -o "$work/out8-jobs" --force --jobs 2 --threads 1 "${ssdo_args[@]}" >/dev/null; t1=$(now)
printf '8 frames, %-40s %.2f s, %.3f frames/s\n' "ssdo process --jobs 2 --threads 1:" "$(calc "$t1 - $t0")" "$(calc "8 / ($t1 - $t0)")"
t0=$(now)
for i in a b c d e f g h; do oiiotool "$work/eight/f$i.exr" --ch "$layer" -d half --compression zip -o "$work/copy$i.exr"; done
t1=$(now)
printf '8 frames, %-40s %.2f s, %.3f frames/s\n' "oiiotool channel copy:" "$(calc "$t1 - $t0")" "$(calc "8 / ($t1 - $t0)")"
echo "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"
