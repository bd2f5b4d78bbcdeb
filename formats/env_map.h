// Reading an environment map (equirectangular latitude-longitude radiance image) into the
// CV_32FC3 RGB image kernels/environment.h takes. EXR (R, G, B or Y channels) is read with
// OpenEXR; any other format OpenImageIO reads (HDR, TIFF, ...) through the OpenImageIO
// module (formats/oiio_module.h).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "formats/exr_header_check.h"

namespace ssdo {

struct EnvMapResult {
  cv::Mat radiance_rgb;  // CV_32FC3 (R, G, B), linear, row 0 = top (straight up)
  std::string error;     // empty on success, else names the file and the problem
  bool ok() const { return error.empty(); }
};

// The brightest radiance an environment texel keeps: above any captured sky (an HDR
// capture's sun disk is ~1e5-1e8 in its units), and small enough that the projection's
// sums of texels times solid angles stay finite in float (3.4e38).
inline constexpr float kMaxEnvRadiance = 1e9f;

// Reads the first three channels (R, G, B; a single channel is replicated) as linear
// radiance (an 8-bit sRGB or gamma-encoded image is decoded). The map is the display
// window: an EXR data window covering part of it is placed in it, black elsewhere. Refuses
// a map that is not 2:1 (within 5% or a pixel: another projection) and images larger than
// max_pixels, both before allocating; non-finite or negative radiance is read
// as 0 (a map with no other value is refused), radiance above kMaxEnvRadiance as it.
EnvMapResult read_env_map(const std::string& path, long long max_pixels = kDefaultMaxPixels);

// What read_env_map would refuse that is known without decoding the pixels: for EXR the
// header (formats/exr_header_check.h), the size limit, the 2:1 shape and the channels; any
// other format its header's size, shape and channels through OpenImageIO, nothing decoded. Empty on success, else the
// error. For a process that checks options before a worker reads the map (a service's
// client names it: its pixels are decoded by the worker only).
std::string check_env_map(const std::string& path, long long max_pixels = kDefaultMaxPixels);

}  // namespace ssdo
