// The kernels give the same bits on every instruction set they are compiled for
// (core/simd.h): the best one this CPU runs against the baseline fallback, on a frame
// whose odd width sends pixels down both the vector and the per-pixel paths.
#include "core/simd.h"

#include <gtest/gtest.h>

#include "kernels/confidence.h"
#include "kernels/denoise.h"
#include "kernels/half_resolution.h"
#include "kernels/normals.h"
#include "kernels/ssdo.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

struct Terms {
  TermOutputs terms;
  cv::Mat normals, denoised, blurred;
};

Terms all_terms(const GBuffer& g, const Environment& sky) {
  AoSettings ao = ao_preset(AoMethod::gtao, Preset::medium);
  ao.multibounce = true;
  const SsdoSettings light = ssdo_preset(SsdoMethod::ssdo, Preset::medium);
  const ConfidenceSettings confidence;
  Terms t;
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &sky, &g.albedo};
  compute_terms(in, {&ao, &light, &confidence}, t.terms, {}, 2);
  reconstruct_normals_from_depth(g.depth_view, g.mask, g.camera, t.normals, {}, 2);
  denoise_bilateral(t.terms.ao.ao, g.depth_view, g.normal_view, g.mask, DenoiseSettings{}, t.denoised, {}, 2);
  box_blur_4x4(t.terms.ssdo.indirect, t.blurred, {}, 2);
  return t;
}

double differing(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return -1.0;
  return cv::norm(a, b, cv::NORM_INF);
}

TEST(Simd, EveryInstructionSetGivesTheSameBits) {
  const GBuffer g = raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(203, 97), 0);
  const Environment sky = Environment::sky(SkyGradient{});
  const bool was_baseline = simd_target() == simd_baseline_target();
  use_best_simd();
  const std::string best = simd_target();
  const Terms on_best = all_terms(g, sky);
  use_baseline_simd();
  EXPECT_EQ(simd_target(), simd_baseline_target());
  const Terms on_baseline = all_terms(g, sky);
  if (!was_baseline) use_best_simd();
  EXPECT_LT(cv::mean(on_best.terms.ao.ao)[0], 0.99);  // something is occluded
  EXPECT_EQ(differing(on_best.terms.ao.ao, on_baseline.terms.ao.ao), 0.0) << best;
  EXPECT_EQ(differing(on_best.terms.ao.bent_normal_view, on_baseline.terms.ao.bent_normal_view), 0.0) << best;
  EXPECT_EQ(differing(on_best.terms.ssdo.direct, on_baseline.terms.ssdo.direct), 0.0) << best;
  EXPECT_EQ(differing(on_best.terms.ssdo.indirect, on_baseline.terms.ssdo.indirect), 0.0) << best;
  EXPECT_EQ(differing(on_best.terms.confidence, on_baseline.terms.confidence), 0.0) << best;
  EXPECT_EQ(differing(on_best.normals, on_baseline.normals), 0.0) << best;
  EXPECT_EQ(differing(on_best.denoised, on_baseline.denoised), 0.0) << best;
  EXPECT_EQ(differing(on_best.blurred, on_baseline.blurred), 0.0) << best;
}

}  // namespace
}  // namespace ssdo
