// Neighbouring frames as extra views (kernels/multiview.h) on the shared orbit shot
// (orbit_f0..f6: the greeble, the camera orbiting 5 degrees per frame, Cycles AO within 1
// unit): the denoised AO of each frame computed alone and with its neighbours' depth,
// against Cycles' AO pass. The shot must improve and no frame may get worse by more than
// 2% of its single-frame error.
#include <cstdio>
#include <filesystem>
#include <map>

#include <gtest/gtest.h>

#include "service/frame_inputs.h"
#include "shot_views.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

constexpr int kOrbitFrames = 7;

struct OrbitFrame {
  GBuffer g;
  cv::Mat reference;  // Cycles AO, CV_32FC1
  float radius_world = 1.0f;
};

const OrbitFrame& orbit(int t) {
  static std::map<int, OrbitFrame> cache;
  if (auto it = cache.find(t); it != cache.end()) return it->second;
  OrbitFrame& f = cache[t];
  ReadOptions options;
  options.read_references = true;
  const std::string path = (fs::path(SSDO_SHARED_DIR) / "gbuffers" / ("orbit_f" + std::to_string(t) + ".exr")).string();
  ReadResult r = read_frame(path, options);
  EXPECT_TRUE(r.ok()) << r.error;
  f.g = std::move(r.gbuffer);
  if (r.info.ao_distance_world) f.radius_world = *r.info.ao_distance_world;
  cv::extractChannel(f.g.references.at("AO"), f.reference, 0);
  return f;
}

// Frame t's denoised AO with the frames t-k..t+k (within the shot) as views.
shot::Measured measure(int t, int k, AoMethod method, Preset preset) {
  const OrbitFrame& f = orbit(t);
  const GBuffer g = shot::with_views(
      t, k, kOrbitFrames, [](int u) -> const GBuffer& { return orbit(u).g; },
      [](int u) { return "orbit_f" + std::to_string(u); });
  return shot::measure_denoised_ao(g, method, preset, f.radius_world, f.reference, f.g.mask);
}

TEST(MultiViewAccuracy, OrbitImprovesAndNoFrameGetsWorse) {
  for (const auto& [method, preset] : {std::pair{AoMethod::gtao, Preset::medium}, std::pair{AoMethod::gtao, Preset::high}}) {
    double alone = 0, with = 0;
    for (int t = 0; t < kOrbitFrames; ++t) {
      const shot::Measured a = measure(t, 0, method, preset);
      std::printf("%s %s f%d:", std::string(to_string(method)).c_str(), std::string(to_string(preset)).c_str(), t);
      std::printf("  K=0 %.4f (%.0f ms)", a.whole.mae, a.ms);
      for (int k : {1, 2, 3}) {
        const shot::Measured v = measure(t, k, method, preset);
        std::printf("  K=%d %.4f (%.0f ms)", k, v.whole.mae, v.ms);
        if (k == 3) {
          EXPECT_LE(v.whole.mae, a.whole.mae * 1.02) << "frame " << t;
          with += v.whole.mae;
        }
      }
      std::printf("\n");
      alone += a.whole.mae;
    }
    EXPECT_LT(with, alone);
  }
}

}  // namespace
}  // namespace ssdo
