// Neighbouring frames as extra views (kernels/multiview.h) on the shared orbit shot
// (orbit_f0..f6: the greeble, the camera orbiting 5 degrees per frame, Cycles AO within 1
// unit): the denoised AO of each frame computed alone and with its neighbours' depth,
// against Cycles' AO pass. The shot must improve and no frame may get worse by more than
// 2% of its single-frame error.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>

#include <gtest/gtest.h>

#include "kernels/metrics.h"
#include "service/frame_inputs.h"
#include "service/pipeline.h"

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

struct Measured {
  double mae = 0, ms = 0;
};

// Frame t's denoised AO with the frames t-k..t+k (within the shot) as views.
Measured measure(int t, int k, AoMethod method, Preset preset) {
  const OrbitFrame& f = orbit(t);
  GBuffer g = f.g;
  for (int u = std::max(0, t - k); u <= std::min(kOrbitFrames - 1, t + k); ++u)
    if (u != t) g.views.push_back({orbit(u).g.camera, orbit(u).g.depth_view, "orbit_f" + std::to_string(u)});
  FrameRequest request;
  request.ao = ao_preset(method, preset);
  request.ao.radius_world = f.radius_world;
  request.terms.composite = false;
  const auto t0 = std::chrono::steady_clock::now();
  const ComputedFrame out = compute_frame(g, request);
  Measured m;
  m.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  m.mae = compare_images(*out.find("ao_denoised"), f.reference, f.g.mask).mae;
  return m;
}

TEST(MultiViewAccuracy, OrbitImprovesAndNoFrameGetsWorse) {
  for (const auto& [method, preset] : {std::pair{AoMethod::gtao, Preset::medium}, std::pair{AoMethod::gtao, Preset::high}}) {
    double alone = 0, with = 0;
    for (int t = 0; t < kOrbitFrames; ++t) {
      const Measured a = measure(t, 0, method, preset);
      std::printf("%s %s f%d:", std::string(to_string(method)).c_str(), std::string(to_string(preset)).c_str(), t);
      std::printf("  K=0 %.4f (%.0f ms)", a.mae, a.ms);
      for (int k : {1, 2, 3}) {
        const Measured v = measure(t, k, method, preset);
        std::printf("  K=%d %.4f (%.0f ms)", k, v.mae, v.ms);
        if (k == 3) {
          EXPECT_LE(v.mae, a.mae * 1.02) << "frame " << t;
          with += v.mae;
        }
      }
      std::printf("\n");
      alone += a.mae;
    }
    EXPECT_LT(with, alone);
  }
}

}  // namespace
}  // namespace ssdo
