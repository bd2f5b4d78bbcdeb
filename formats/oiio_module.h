// OpenImageIO, loaded on first use. OpenImageIO and the ~250 shared libraries it depends on
// (codecs, GDAL, GStreamer, ...) cost more dynamic linking per process start than reading
// a 1080p frame takes. The hot path (EXR frames in, EXR terms out) uses OpenEXR
// alone, so OpenImageIO lives in a module (libssdo_oiio.so, beside the ssdo binary) that
// the functions below load the first time they need it: environment maps in formats other
// than EXR, PNG previews and charts.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace ssdo::oiio_module {

// Threads OpenImageIO may use once loaded (applied at load, and at once if loaded).
void set_threads(int threads);

// Whether the module has been loaded in this process.
bool loaded();

// Loads the module now (e.g. before a memory limit); "" or why it cannot be loaded.
std::string load();

// The first min(channels, max_channels) channels of any image OpenImageIO reads, as float.
// "" on success, else the error (naming the file).
std::string read_image(const std::string& path, int max_channels, long long max_pixels,
                       cv::Mat& pixels);

// An 8-bit image (CV_8UC1/3/4, continuous) written as PNG at `path`; colour_space is
// recorded in the file ("sRGB" or "Linear"). "" or the error.
std::string write_png(const std::string& path, const cv::Mat& pixels_u8,
                      const std::string& colour_space);

}  // namespace ssdo::oiio_module
