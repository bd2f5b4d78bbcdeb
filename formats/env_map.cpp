#include "formats/env_map.h"

#include <cmath>
#include <exception>

#include <OpenImageIO/imageio.h>

namespace ssdo {

EnvMapResult read_env_map(const std::string& path, long long max_pixels) {
  EnvMapResult r;
  try {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
      r.error = path + ": cannot open the environment map: " + OIIO::geterror();
      return r;
    }
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 ||
        (long long)spec.width * spec.height > max_pixels) {
      r.error = path + ": environment map size " + std::to_string(spec.width) + " x " +
                std::to_string(spec.height) + " is empty or larger than the limit of " +
                std::to_string(max_pixels) + " pixels";
      return r;
    }
    const int channels = std::min(spec.nchannels, 3);
    cv::Mat pixels(spec.height, spec.width, CV_32FC(channels));
    if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data)) {
      r.error = path + ": cannot read the environment map: " + in->geterror();
      return r;
    }
    if (channels == 3) {
      r.radiance_rgb = pixels;
    } else if (channels == 1) {
      cv::merge(std::vector<cv::Mat>{pixels, pixels, pixels}, r.radiance_rgb);
    } else {
      r.error = path + ": the environment map has 2 channels; expected RGB or one luminance channel";
      return r;
    }
    // Radiance is finite and >= 0: anything else (NaN, Inf, negative from a bad filter)
    // would poison the SH projection and every pixel with it.
    for (int y = 0; y < r.radiance_rgb.rows; ++y) {
      float* p = r.radiance_rgb.ptr<float>(y);
      for (int i = 0; i < r.radiance_rgb.cols * 3; ++i)
        if (!std::isfinite(p[i]) || p[i] < 0.0f) p[i] = 0.0f;
    }
  } catch (const std::exception& e) {
    r.error = path + ": cannot read the environment map: " + e.what();
  }
  return r;
}

}  // namespace ssdo
