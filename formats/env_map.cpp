#include "formats/env_map.h"

#include <cmath>
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

// The header checks of an EXR map: the channels read ({R, G, B} or {Y, Y, Y}) in
// `names`, or the error.
std::string check_exr(const std::string& path, long long max_pixels, const Imf::Header& header,
                      std::vector<std::string>& names) {
  const Imath::Box2i data = header.dataWindow();
  const long long w = (long long)data.max.x - data.min.x + 1;
  const long long h = (long long)data.max.y - data.min.y + 1;
  if (w <= 0 || h <= 0 || w * h > max_pixels)
    return path + ": environment map size " + std::to_string(w) + " x " + std::to_string(h) +
           " is empty or larger than the limit of " + std::to_string(max_pixels) + " pixels";
  const Imf::ChannelList& channels = header.channels();
  if (channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B"))
    names = {"R", "G", "B"};
  else if (channels.findChannel("Y"))
    names = {"Y", "Y", "Y"};
  else {
    std::string found;
    for (auto it = channels.begin(); it != channels.end(); ++it) found += (found.empty() ? "" : ", ") + std::string(it.name());
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

// EXR through OpenEXR (the common case; no OpenImageIO to load): R, G, B, or a luminance
// channel Y replicated. Headers are checked first, as for frames. rgb null: the checks only.
std::string read_exr(const std::string& path, long long max_pixels, cv::Mat* rgb) {
  ExrLimits limits;
  limits.max_pixels = max_pixels;
  if (const ExrHeaderCheck check = check_exr_headers(path, limits); !check.ok())
    return check.error;
  Imf::InputFile in(path.c_str());
  std::vector<std::string> names;
  if (std::string e = check_exr(path, max_pixels, in.header(), names); !e.empty() || rgb == nullptr)
    return e;
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
  return {};
}

}  // namespace

EnvMapResult read_env_map(const std::string& path, long long max_pixels) {
  EnvMapResult r;
  if (r.error = input_file_error(path, "environment map"); !r.error.empty()) return r;
  try {
    if (is_exr(path)) {
      if (std::string e = read_exr(path, max_pixels, &r.radiance_rgb); !e.empty()) {
        r.error = "environment map " + e;
        return r;
      }
    } else {
      cv::Mat pixels;
      if (std::string e = oiio_module::read_image(path, 3, max_pixels, pixels); !e.empty()) {
        r.error = "environment map " + e;
        return r;
      }
      if (pixels.channels() == 3) {
        r.radiance_rgb = pixels;
      } else if (pixels.channels() == 1) {
        cv::merge(std::vector<cv::Mat>{pixels, pixels, pixels}, r.radiance_rgb);
      } else {
        r.error = path + ": the environment map has 2 channels; expected RGB or one luminance channel";
        return r;
      }
    }
    // Radiance is finite and >= 0: anything else (NaN, Inf, negative from a bad filter)
    // would poison the SH projection and every pixel with it. It is at most
    // kMaxEnvRadiance, so that sums of texels times solid angles stay finite.
    for (int y = 0; y < r.radiance_rgb.rows; ++y) {
      float* p = r.radiance_rgb.ptr<float>(y);
      for (int i = 0; i < r.radiance_rgb.cols * 3; ++i)
        p[i] = !std::isfinite(p[i]) || p[i] < 0.0f ? 0.0f : std::min(p[i], kMaxEnvRadiance);
    }
  } catch (const std::exception& e) {
    r.error = path + ": cannot read the environment map: " + e.what();
  }
  return r;
}

std::string check_env_map(const std::string& path, long long max_pixels) {
  if (std::string e = input_file_error(path, "environment map"); !e.empty()) return e;
  // Other formats: their header only (a service checks a client's map without decoding it:
  // a small PNG can declare 8000 x 8000 pixels).
  if (!is_exr(path)) {
    cv::Mat unused;
    const std::string e = oiio_module::read_image(path, 0, max_pixels, unused);
    return e.empty() ? e : "environment map " + e;
  }
  try {
    if (std::string e = read_exr(path, max_pixels, nullptr); !e.empty()) return "environment map " + e;
  } catch (const std::exception& e) {
    return path + ": cannot read the environment map: " + e.what();
  }
  return {};
}

}  // namespace ssdo
