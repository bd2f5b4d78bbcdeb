#include "tests/bench/bench_frames.h"

#include <algorithm>
#include <filesystem>

#include "formats/gbuffer_reader.h"
#include "service/frame_inputs.h"
#include "kernels/positions.h"
#include "tests/support/raycast.h"

namespace ssdo::bench {
namespace {

GBuffer load(int width) {
  const std::filesystem::path dir = std::filesystem::path(SSDO_SHARED_DIR) / "gbuffers";
  const std::filesystem::path file = dir / (width == 640 ? "cornell.exr" : "perf1080.exr");
  if (std::filesystem::exists(file)) {
    ReadOptions options;
    options.read_references = false;
    ReadResult r = read_frame(file.string(), options);
    if (r.ok()) {
      GBuffer g = std::move(r.gbuffer);
      if (g.position_view.empty()) view_positions_from_depth(g.depth_view, g.mask, g.camera, g.position_view);
      return g;
    }
  }
  const int height = width * 9 / 16;
  return raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(width, height), 2);
}

}  // namespace

const GBuffer& frame(int width) {
  static const GBuffer small = load(640);
  static const GBuffer large = load(1920);
  return width == 640 ? small : large;
}

cv::Mat sky_equirect() {
  const cv::Size size(512, 256);
  const SkyGradient sky;
  cv::Mat img(size, CV_32FC3);
  for (int j = 0; j < size.height; ++j)
    for (int i = 0; i < size.width; ++i) {
      const glm::vec3 d = Environment::direction_from_equirect({i + 0.5f, j + 0.5f}, size);
      const float t = std::clamp((d.z - sky.up_begin) / (sky.up_end - sky.up_begin), 0.0f, 1.0f);
      const glm::vec3 l = (1.0f - t) * sky.bottom + t * sky.top;
      img.at<cv::Vec3f>(j, i) = cv::Vec3f(l.x, l.y, l.z);
    }
  return img;
}

const Environment& sky_environment() {
  static const Environment env = Environment::equirect(sky_equirect());
  return env;
}

}  // namespace ssdo::bench
