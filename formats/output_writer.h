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

// Writes all terms into one EXR at `path` (written as a temp file in the same folder,
// then renamed), with the camera carried over as worldToCamera/worldToNDC attributes.
// Returns an empty string on success, else the error.
std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options = {});

}  // namespace ssdo
