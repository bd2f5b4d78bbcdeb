// Small valid G-buffer EXR files for the fuzz seed corpora and the JSON target: every
// profile and layout the reader supports, a few pixels each, with the special values
// the reader must handle (background, NaN, Inf, negative depth, zero normals).
#pragma once

#include <string>

namespace ssdo::fuzz {

// Variants 0 .. kSeedExrVariants - 1:
// 0 Blender multilayer (ViewLayer.Depth.Z, .Normal.XYZ, .DiffCol.RGB, .AO.R), float,
//   no compression, worldToCamera / worldToNDC / clipNear / clipFar in the header;
// 1 generic Z + N.XYZ as half, ZIP, data window inside a larger display window;
// 2 generic depth.Z + P.XYZ + albedo.RGB, RLE, no camera;
// 3 tiled Z + N.RGB, PIZ;
// 4 two parts ("depth" with Z, "color" with R G B) of different data windows;
// 5 deep scanline Z + N.XYZ, 0 to 3 samples per pixel, ZIPS;
// 6 the same deep tiled, RLE.
constexpr int kSeedExrVariants = 7;

// Writes variant `variant` to `path`. False on failure.
bool write_seed_exr(const std::string& path, int variant);

}  // namespace ssdo::fuzz
