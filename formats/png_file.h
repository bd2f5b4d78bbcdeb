// 8-bit PNG files through libpng: the previews of output terms. A small library linked into
// the binary, so that writing previews does not load OpenImageIO and the ~250 shared
// libraries behind it (formats/oiio_module.h) in every worker that writes them.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace ssdo {

// What the samples encode, recorded in the file: sRGB (an sRGB chunk, with the gAMA and
// cHRM that readers without sRGB support use) or linear values (gAMA 1.0).
enum class PngTransfer { srgb, linear };

// `pixels` (CV_8UC1 grey, CV_8UC3 RGB or CV_8UC4 RGBA) written as a PNG file at exactly
// `path` (not through a temporary file: the caller renames), deflated at zlib_level (0-9).
// "" on success, else the error naming the file.
std::string write_png_8bit(const std::string& path, const cv::Mat& pixels, PngTransfer transfer, int zlib_level);

}  // namespace ssdo
