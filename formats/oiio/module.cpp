// The OpenImageIO module: every use of OpenImageIO in the product (images in formats other
// than EXR, charts). Loaded by formats/oiio_module.cpp on first use, so that
// processes which never need it (the workers on EXR frames) do not pay for loading it and
// the ~250 shared libraries it depends on at every process start.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

#include <OpenImageIO/imageio.h>

#include "formats/oiio/module_api.h"

namespace ssdo::oiio_module {

std::string render_chart_png(const std::string& path, const std::vector<ChartSeries>& series,
                             const ChartOptions& options);  // formats/oiio/chart.cpp

namespace {

void set_threads(int threads) {
  OIIO::attribute("threads", threads);
  // -1: leave OpenEXR's pool as the process sized it (1 thread = no pool).
  OIIO::attribute("exr_threads", threads > 1 ? threads : -1);
}

// OpenImageIO's messages may span lines ("...\nPNG library error"): one line.
std::string one_line(std::string text) {
  for (char& c : text)
    if (c == '\n' || c == '\r') c = ' ';
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

// Linear values of an image in a display encoding, in place: the sRGB transfer function
// (IEC 61966-2-1: c / 12.92 up to 0.04045, ((c + 0.055) / 1.055)^2.4 above) for "sRGB",
// c^g for "GammaCorrected<g>"; other colour spaces are taken as linear.
void decode_to_linear(const std::string& color_space, cv::Mat& pixels) {
  std::string cs = color_space;
  for (char& c : cs) c = char(std::tolower(static_cast<unsigned char>(c)));
  const bool srgb = cs == "srgb" || cs.starts_with("srgb_") || cs.starts_with("srgb ");
  float gamma = 0.0f;
  if (cs.starts_with("gammacorrected")) gamma = std::strtof(cs.c_str() + std::string("gammacorrected").size(), nullptr);
  if (!srgb && !(gamma > 0.0f)) return;
  const int n = pixels.cols * pixels.channels();
  for (int y = 0; y < pixels.rows; ++y) {
    float* p = pixels.ptr<float>(y);
    for (int i = 0; i < n; ++i) {
      const float c = std::max(p[i], 0.0f);
      p[i] = srgb ? (c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f)) : std::pow(c, gamma);
    }
  }
}

std::string read_image(const std::string& path, int max_channels, long long max_pixels,
                       cv::Mat& pixels, ImageHeader& header) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return path + ": cannot open: " + one_line(OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  header = {spec.width, spec.height, spec.nchannels, spec.get_string_attribute("oiio:ColorSpace")};
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 ||
      (long long)spec.width * spec.height > max_pixels)
    return path + ": image size " + std::to_string(spec.width) + " x " +
           std::to_string(spec.height) + " is empty or larger than the limit of " +
           std::to_string(max_pixels) + " pixels";
  if (max_channels <= 0) return {};  // the header's checks only
  const int channels = std::min(spec.nchannels, max_channels);
  pixels.create(spec.height, spec.width, CV_32FC(channels));
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data))
    return path + ": cannot read: " + one_line(in->geterror());
  decode_to_linear(header.color_space, pixels);
  return {};
}

constexpr Api kApi{kVersion, set_threads, read_image, render_chart_png};

}  // namespace
}  // namespace ssdo::oiio_module

extern "C" __attribute__((visibility("default"))) const ssdo::oiio_module::Api*
ssdo_oiio_module_api() {
  return &ssdo::oiio_module::kApi;
}
