// The table of functions the OpenImageIO module (libssdo_oiio.so, formats/oiio/*.cpp)
// exports to the loader (formats/oiio_module.cpp). Both sides are built together from this
// header; kVersion guards against a stale module beside a newer binary.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "formats/chart.h"

namespace ssdo::oiio_module {

inline constexpr int kVersion = 5;

// What an image's header says: its size, channel count and colour space.
struct ImageHeader {
  int width = 0, height = 0, channels = 0;
  std::string color_space;  // OpenImageIO's "oiio:ColorSpace" ("sRGB", "Linear", ...)
};

struct Api {
  int version = kVersion;
  // OpenImageIO's pool size and the OpenEXR pool size it sets when it opens an EXR.
  void (*set_threads)(int threads) = nullptr;
  // The first min(channels, max_channels) channels of subimage 0 as linear float (an sRGB or
  // gamma-encoded image decoded); "" or the error. Sizes over max_pixels are refused before
  // allocating. max_channels 0: the header's checks only (nothing decoded, `pixels`
  // untouched). `header` is filled whenever the header reads.
  std::string (*read_image)(const std::string& path, int max_channels, long long max_pixels,
                            cv::Mat& pixels, ImageHeader& header) = nullptr;
  std::string (*write_chart_png)(const std::string& path, const std::vector<ChartSeries>& series,
                                 const ChartOptions& options) = nullptr;
};

}  // namespace ssdo::oiio_module

// The module's one exported symbol.
extern "C" const ssdo::oiio_module::Api* ssdo_oiio_module_api();
