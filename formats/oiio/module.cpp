// The OpenImageIO module: every use of OpenImageIO in the product (images in formats other
// than EXR, charts). Loaded by formats/oiio_module.cpp on first use, so that
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
  if (max_channels <= 0) return {};  // the header's checks only
  const int channels = std::min(spec.nchannels, max_channels);
  pixels.create(spec.height, spec.width, CV_32FC(channels));
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data))
    return path + ": cannot read: " + in->geterror();
  return {};
}

constexpr Api kApi{kVersion, set_threads, read_image, render_chart_png};

}  // namespace
}  // namespace ssdo::oiio_module

extern "C" __attribute__((visibility("default"))) const ssdo::oiio_module::Api*
ssdo_oiio_module_api() {
  return &ssdo::oiio_module::kApi;
}
