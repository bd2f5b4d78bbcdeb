#!/usr/bin/env bash
# SSDO next to Cycles on the shared frames: per scene, Cycles' DiffDir, ssdo's direct term,
# Cycles' DiffInd, ssdo's indirect term (x4, the same scale for both), and the composite
# (albedo x (direct + indirect), the frame's own lighting replaced by ssdo's) next to
# Cycles' Combined. Writes examples/ssdo/side_by_side.png.
#   examples/ssdo/side_by_side.sh [SSDO_BINARY] [SHARED_GBUFFERS_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
ssdo=${1:-build/ssdo}
shared=${2:-../shared/gbuffers}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$ssdo" process "$shared"/cornell.exr "$shared"/greeble.exr "$shared"/depthgap.exr -o "$work" \
  --terms ssdo --ssdo-preset medium --env "$shared"/env_equirect.exr --composite ssdo >/dev/null
font=/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf
tiles=()
for scene in cornell greeble depthgap; do
  in="$shared/$scene.exr" out="$work/$scene.ssdo.exr"
  tile() {  # FILE CHANNEL_PREFIX SCALE LABEL NAME
    oiiotool "$1" --ch "$2.R,$2.G,$2.B" --chnames R,G,B --mulc "$3" --clamp:min=0:max=1 --powc 0.4545 \
      --resize 320x180 --text:x=6:y=18:size=14:color=1,1,1:font="$font" "$scene: $4" \
      -d uint8 -o "$work/$5.png"
    tiles+=("$work/$5.png")
  }
  tile "$in" ViewLayer.DiffDir 1 "Cycles DiffDir" "${scene}_a"
  tile "$out" ssdo_direct_denoised 1 "ssdo direct" "${scene}_b"
  tile "$in" ViewLayer.DiffInd 4 "Cycles DiffInd x4" "${scene}_c"
  tile "$out" ssdo_indirect_denoised 4 "ssdo indirect x4" "${scene}_d"
  tile "$in" ViewLayer.Combined 1 "Cycles Combined" "${scene}_e"
  tile "$out" composite 1 "ssdo composite" "${scene}_f"
done
oiiotool "${tiles[@]}" --mosaic:pad=2 6x3 -d uint8 -o examples/ssdo/side_by_side.png
echo "wrote examples/ssdo/side_by_side.png"
