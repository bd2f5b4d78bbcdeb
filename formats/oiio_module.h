// OpenImageIO, loaded on first use. OpenImageIO and the ~250 shared libraries it depends on
// (codecs, GDAL, GStreamer, ...) cost more dynamic linking per process start than reading
// a 1080p frame takes. The hot path (EXR frames in, EXR terms out) uses OpenEXR
// alone, so OpenImageIO lives in a module (libssdo_oiio.so, beside the ssdo binary) that
// the functions below load the first time they need it: environment maps in formats other
// than EXR, and charts (PNG previews are written by libpng, formats/png_file.h).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "formats/oiio/module_api.h"

namespace ssdo::oiio_module {

// Threads OpenImageIO may use once loaded (applied at load, and at once if loaded).
void set_threads(int threads);

// Whether the module has been loaded in this process.
bool loaded();

// Loads the module now (e.g. before a memory limit); "" or why it cannot be loaded.
std::string load();

// The first min(channels, max_channels) channels of any image OpenImageIO reads, as linear
// float (8-bit sRGB or gamma-encoded images decoded, as their "oiio:ColorSpace" says).
// "" on success, else the error (naming the file). max_channels 0: only what the header
// says is checked (a size over max_pixels, an empty image); nothing is decoded. `header`
// (formats/oiio/module_api.h) is filled whenever the header reads.
std::string read_image(const std::string& path, int max_channels, long long max_pixels,
                       cv::Mat& pixels, ImageHeader& header);

}  // namespace ssdo::oiio_module
