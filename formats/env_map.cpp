#include "formats/env_map.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <fstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include "formats/exr_header_check.h"
#include "formats/gbuffer_reader.h"
#include "formats/input_file.h"
#include "formats/oiio_module.h"

namespace ssdo {
namespace {

bool is_exr(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char magic[4] = {};
  in.read(reinterpret_cast<char*>(magic), 4);
  return in && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
}

// An equirectangular map spans 360 x 180 degrees: its width is twice its height (within 5%
// or a pixel, for exports rounded to odd sizes). Any other shape is another projection (a
// square mirror ball or angular map, a 4:3 or 3:4 cube cross, a 6:1 or 1:6 strip of cube
// faces) or a crop, which read as latitude-longitude would light every pixel from the
// wrong direction.
std::string aspect_error(const std::string& path, long long width, long long height) {
  if (std::llabs(width - 2 * height) <= std::max(1LL, width / 20)) return {};
  return path + ": the environment map is " + std::to_string(width) + " x " + std::to_string(height) +
         ", not 2:1: an equirectangular (latitude-longitude) map spans 360 x 180 degrees; convert another "
         "projection (mirror ball, angular map, cube cross or strip) to latitude-longitude first";
}

// The header checks of an EXR map: the channels read ({R, G, B} or {Y, Y, Y}) in
// `names`, or the error.
std::string check_exr(const std::string& path, long long max_pixels, const Imf::Header& header,
                      std::vector<std::string>& names) {
  for (const Imath::Box2i& box : {header.dataWindow(), header.displayWindow()}) {
    const long long w = (long long)box.max.x - box.min.x + 1;
    const long long h = (long long)box.max.y - box.min.y + 1;
    if (w <= 0 || h <= 0 || w * h > max_pixels)
      return path + ": environment map size " + std::to_string(w) + " x " + std::to_string(h) +
             " is empty or larger than the limit of " + std::to_string(max_pixels) + " pixels";
  }
  const Imath::Box2i display = header.displayWindow();
  if (std::string e = aspect_error(path, (long long)display.max.x - display.min.x + 1,
                                   (long long)display.max.y - display.min.y + 1);
      !e.empty())
    return e;
  const Imf::ChannelList& channels = header.channels();
  if (channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B"))
    names = {"R", "G", "B"};
  else if (channels.findChannel("Y"))
    names = {"Y", "Y", "Y"};
  else {
    std::string found;
    for (auto it = channels.begin(); it != channels.end(); ++it)
      found += (found.empty() ? "" : ", ") + std::string(it.name());
    return path + ": the environment map needs channels R, G and B, or Y (it has " + found + ")";
  }
  return {};
}

// A luminance map read into component 0: copied to G and B.
void replicate_luminance(const std::vector<std::string>& names, cv::Mat& rgb) {
  if (names[0] != "Y") return;
  for (int y = 0; y < rgb.rows; ++y) {
    float* p = rgb.ptr<float>(y);
    for (int x = 0; x < rgb.cols; ++x) p[3 * x + 1] = p[3 * x + 2] = p[3 * x];
  }
}

// The map is its display window (the whole sphere), whose pixels the data window may cover
// only in part (a map cropped to its bright region, Nuke's bounding boxes): the data window
// placed in it, black (no light) where it holds no pixels, and what lies outside the
// display window dropped.
void place_in_display_window(const Imf::Header& header, cv::Mat& rgb) {
  const Imath::Box2i data = header.dataWindow(), display = header.displayWindow();
  if (data == display) return;
  const long long w = (long long)display.max.x - display.min.x + 1;
  const long long h = (long long)display.max.y - display.min.y + 1;
  cv::Mat full = cv::Mat::zeros(int(h), int(w), CV_32FC3);
  const cv::Rect data_in_display(data.min.x - display.min.x, data.min.y - display.min.y, rgb.cols, rgb.rows);
  const cv::Rect common = data_in_display & cv::Rect(0, 0, full.cols, full.rows);
  if (common.area() > 0)
    rgb(common - data_in_display.tl()).copyTo(full(common));
  rgb = full;
}

// EXR through OpenEXR (the common case; no OpenImageIO to load): R, G, B, or a luminance
// channel Y replicated. Headers are checked first, as for frames. rgb null: the checks only.
std::string read_exr(const std::string& path, long long max_pixels, cv::Mat* rgb) {
  ExrLimits limits;
  limits.max_pixels = max_pixels;
  const ExrHeaderCheck check = check_exr_headers(path, limits);
  if (!check.ok()) return check.error;
  Imf::InputFile in(path.c_str());
  std::vector<std::string> names;
  if (std::string e = check_exr(path, max_pixels, in.header(), names); !e.empty() || rgb == nullptr) {
    if (!e.empty() && check.parts.size() > 1)  // InputFile reads the first part
      e += " in its first part; the map is read from the first of its " + std::to_string(check.parts.size()) + " parts";
    return e;
  }
  const Imath::Box2i data = in.header().dataWindow();
  const long long w = (long long)data.max.x - data.min.x + 1;
  const long long h = (long long)data.max.y - data.min.y + 1;
  cv::Mat& out = *rgb;
  out.create(int(h), int(w), CV_32FC3);
  // ZIP, ZIPS and uncompressed scanlines through the G-buffer reader's decoder (the
  // OpenEXR calls below give the same floats, slower).
  const std::vector<ChannelComponent> wanted =
      names[0] == "Y" ? std::vector<ChannelComponent>{{"Y", 0}}
                      : std::vector<ChannelComponent>{{"R", 0}, {"G", 1}, {"B", 2}};
  if (read_scanline_channels(path, wanted, out)) {
    replicate_luminance(names, out);
    place_in_display_window(in.header(), out);
    return {};
  }
  // Slices address pixel (x, y) of the data window at base + x * xStride + y * yStride.
  char* base = reinterpret_cast<char*>(out.ptr<float>(0)) -
               (data.min.x * 3 + (long long)data.min.y * w * 3) * (long long)sizeof(float);
  Imf::FrameBuffer fb;
  if (names[0] == "Y") {
    fb.insert("Y", Imf::Slice(Imf::FLOAT, base, 3 * sizeof(float), size_t(w) * 3 * sizeof(float)));
  } else {
    for (int c = 0; c < 3; ++c)
      fb.insert(names[size_t(c)], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float),
                                             size_t(w) * 3 * sizeof(float)));
  }
  in.setFrameBuffer(fb);
  in.readPixels(data.min.y, data.max.y);
  replicate_luminance(names, out);
  place_in_display_window(in.header(), out);
  return {};
}


// A map other than EXR: its channels as RGB (one luminance channel replicated), or why not.
std::string channels_error(const std::string& path, int channels) {
  if (channels == 1 || channels >= 3) return {};
  return path + ": the environment map has " + std::to_string(channels) +
         " channels; expected RGB or one luminance channel";
}

std::string read_other_format(const std::string& path, long long max_pixels, cv::Mat& rgb) {
  cv::Mat pixels;
  oiio_module::ImageHeader header;
  // One read: the size is refused before decoding; a two-channel image only after.
  if (std::string e = oiio_module::read_image(path, 3, max_pixels, pixels, header); !e.empty())
    return "environment map " + e;
  if (std::string e = channels_error(path, header.channels); !e.empty()) return e;
  if (std::string e = aspect_error(path, header.width, header.height); !e.empty()) return e;
  if (pixels.channels() == 3) rgb = pixels;
  else cv::merge(std::vector<cv::Mat>{pixels, pixels, pixels}, rgb);
  return {};
}

// Radiance is finite and >= 0: anything else (NaN, Inf, negative from a bad filter) would
// poison the SH projection and every pixel with it, and is read as 0. It is at most
// kMaxEnvRadiance, so that sums of texels times solid angles stay finite. A map with no
// valid texel at all is not a dark sky but a broken file: refused.
std::string sanitise_radiance(const std::string& path, cv::Mat& rgb) {
  size_t valid = 0;
  for (int y = 0; y < rgb.rows; ++y) {
    float* p = rgb.ptr<float>(y);
    for (int i = 0; i < rgb.cols * 3; ++i) {
      const bool ok = std::isfinite(p[i]) && p[i] >= 0.0f;
      valid += ok;
      p[i] = ok ? std::min(p[i], kMaxEnvRadiance) : 0.0f;
    }
  }
  return valid > 0 ? std::string()
                   : path + ": every value of the environment map is NaN, infinite or negative: it gives no light";
}

}  // namespace

EnvMapResult read_env_map(const std::string& path, long long max_pixels) {
  EnvMapResult r;
  if (r.error = input_file_error(path, "environment map"); !r.error.empty()) return r;
  try {
    if (is_exr(path)) {
      if (std::string e = read_exr(path, max_pixels, &r.radiance_rgb); !e.empty()) r.error = "environment map " + e;
    } else {
      r.error = read_other_format(path, max_pixels, r.radiance_rgb);
    }
    if (r.ok()) r.error = sanitise_radiance(path, r.radiance_rgb);
  } catch (const std::exception& e) {
    r.error = path + ": cannot read the environment map: " + e.what();
  }
  if (!r.ok()) r.radiance_rgb.release();
  return r;
}

std::string check_env_map(const std::string& path, long long max_pixels) {
  if (std::string e = input_file_error(path, "environment map"); !e.empty()) return e;
  // Other formats: their header only (a service checks a client's map without decoding it:
  // a small PNG can declare 8000 x 8000 pixels).
  if (!is_exr(path)) {
    cv::Mat unused;
    oiio_module::ImageHeader header;
    if (const std::string e = oiio_module::read_image(path, 0, max_pixels, unused, header); !e.empty())
      return "environment map " + e;
    if (std::string e = channels_error(path, header.channels); !e.empty()) return e;
    return aspect_error(path, header.width, header.height);
  }
  try {
    if (std::string e = read_exr(path, max_pixels, nullptr); !e.empty()) return "environment map " + e;
  } catch (const std::exception& e) {
    return path + ": cannot read the environment map: " + e.what();
  }
  return {};
}

}  // namespace ssdo
