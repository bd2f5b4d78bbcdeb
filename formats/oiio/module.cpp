// The OpenImageIO module: every use of OpenImageIO in the product (images in formats other
// than EXR, PNG previews, charts). Loaded by formats/oiio_module.cpp on first use, so that
// processes which never need it (the workers on EXR frames) do not pay for loading it and
// the ~250 shared libraries it depends on at every process start.
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

std::string read_image(const std::string& path, int max_channels, long long max_pixels,
                       cv::Mat& pixels) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return path + ": cannot open: " + OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 ||
      (long long)spec.width * spec.height > max_pixels)
    return path + ": image size " + std::to_string(spec.width) + " x " +
           std::to_string(spec.height) + " is empty or larger than the limit of " +
           std::to_string(max_pixels) + " pixels";
  const int channels = std::min(spec.nchannels, max_channels);
  pixels.create(spec.height, spec.width, CV_32FC(channels));
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data))
    return path + ": cannot read: " + in->geterror();
  return {};
}

constexpr int kPngCompressionLevel = 1;

std::string write_png(const std::string& path, const cv::Mat& pixels_u8,
                      const std::string& colour_space) {
  if (pixels_u8.depth() != CV_8U || !pixels_u8.isContinuous())
    return path + ": PNG pixels must be continuous 8-bit";
  auto out = OIIO::ImageOutput::create("png");
  if (!out) return path + ": no PNG writer: " + OIIO::geterror();
  OIIO::ImageSpec spec(pixels_u8.cols, pixels_u8.rows, pixels_u8.channels(), OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", colour_space);
  // zlib level 1 (OpenImageIO's default is 6): a preview is looked at, not archived; level 1
  // deflates a 640x360 term ~4x faster for files ~1.3x larger.
  spec.attribute("png:compressionLevel", kPngCompressionLevel);
  bool ok = out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, pixels_u8.data);
  ok = out->close() && ok;
  std::string error;
  if (!ok) error = path + ": " + out->geterror();
  return error;
}

constexpr Api kApi{kVersion, set_threads, read_image, write_png, render_chart_png};

}  // namespace
}  // namespace ssdo::oiio_module

extern "C" __attribute__((visibility("default"))) const ssdo::oiio_module::Api*
ssdo_oiio_module_api() {
  return &ssdo::oiio_module::kApi;
}
