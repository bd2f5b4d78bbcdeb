#!/usr/bin/env bash
# The main job on the bundled example frames: AO, SSDO and the composite for every frame
# in examples/frames/, written to examples/out/ (one EXR per frame plus PNG previews).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
ssdo="${SSDO:-$here/../build/ssdo}"
out="$here/out"
"$ssdo" process "$here/frames" -o "$out" --terms all --env "$here/env_equirect.exr" \
  --method gtao --preset high --png --force -v
echo
echo "Outputs in $out:"
for f in "$out"/*.ssdo.exr; do
  echo "  $f  (channels: ao, ao_denoised, bent_normal, confidence, ssdo_direct[_denoised],"
  echo "   ssdo_indirect[_denoised], composite)"
done
echo "  previews: $(ls "$out"/*.png 2>/dev/null | wc -l) PNG files ($out/NAME.ssdo.<term>.png)"
echo
echo "Accuracy against Cycles' ray-traced AO pass:"
"$ssdo" eval "$here"/frames/*.exr --reference AO --method gtao --preset high
