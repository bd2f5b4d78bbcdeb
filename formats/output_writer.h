// Writing a frame's results: one multi-channel EXR (named channels, temp file + rename),
// and optional tonemapped sRGB PNG previews.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kernels/camera.h"

namespace ssdo {

enum class SampleType { half, float32 };

// One output term: CV_32FC1 (channel "<name>") or CV_32FC3 (channels "<name>.R/G/B", or
// "<name>.X/Y/Z" when `vector` is set, e.g. a bent normal).
struct OutputTerm {
  std::string name;     // "ao", "bent_normal", "ssdo_direct", "composite", ...
  cv::Mat image;
  SampleType type = SampleType::half;
  bool vector = false;  // components named X, Y, Z instead of R, G, B
};

struct WriteOptions {
  std::string compression = "zip";  // zip | zips | piz | none (dwaa: colour terms only)
  bool png_previews = false;        // NAME.<term>.png beside the EXR
};

// This host's name as it appears in temp file names (".NAME.tmp-<host>-<pid>-<random>"):
// letters, digits, '.' and '_' only.
std::string temp_file_host();

// Writes all terms into one scanline EXR at `path`: written as ".NAME.tmp-<host>-<pid>-<rnd>"
// in the same folder and renamed into place, so the file is complete or absent (on failure
// the temp file is removed and an existing `path` is left as it was). All terms must share
// one size, equal to the camera grid when camera.width_px > 0. Compression "dwaa" is lossy
// and refused for 1-channel (numeric) and vector terms.
// The camera is carried over as worldToCamera (OpenEXR convention: camera looks down +Z,
// i.e. our view space with z negated) and worldToNDC (display window = the terms' grid),
// plus float attributes clipNear / clipFar when known: read_gbuffer reads them back.
// png_previews: "DIR/STEM.<term>.png" beside "DIR/STEM.exr", 8-bit, clamped to [0, 1]
// and sRGB-encoded; vector terms are shown as 0.5 v + 0.5 without sRGB encoding (the usual
// normal-map colours). Previews are written through temp files too.
// Returns an empty string on success, else the error (naming the file).
std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options = {});

}  // namespace ssdo
