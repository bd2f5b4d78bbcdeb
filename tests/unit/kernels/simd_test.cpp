// The kernels give the same bits on every instruction set they are compiled for
// (core/simd.h): the best one this CPU runs against the baseline fallback, on a frame
// whose odd width sends pixels down both the vector and the per-pixel paths, alone and with
// two other views of the scene.
#include "core/simd.h"

#include <array>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "kernels/confidence.h"
#include "kernels/denoise.h"
#include "kernels/half_resolution.h"
#include "kernels/normals.h"
#include "kernels/ssdo.h"
#include "kernels/temporal.h"
#include "kernels/temporal_change.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

struct Terms {
  TermOutputs terms;
  cv::Mat normals, denoised, blurred;
};

Terms all_terms(const GBuffer& g, const Environment& sky, std::span<const DepthView> views = {}, int threads = 2) {
  AoSettings ao = ao_preset(AoMethod::gtao, Preset::medium);
  ao.multibounce = true;
  const SsdoSettings light = ssdo_preset(SsdoMethod::ssdo, Preset::medium);
  const ConfidenceSettings confidence;
  Terms t;
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &sky, &g.albedo,
                      &g.lighting,  nullptr,       views};
  compute_terms(in, {&ao, &light, &confidence}, t.terms, {}, threads);
  reconstruct_normals_from_depth(g.depth_view, g.mask, g.camera, t.normals, {}, threads);
  denoise_bilateral(t.terms.ao.ao, g.depth_view, g.normal_view, g.mask, DenoiseSettings{}, t.denoised, {}, threads);
  box_blur_4x4(t.terms.ssdo.indirect, t.blurred, {}, threads);
  return t;
}

double differing(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return -1.0;
  return cv::norm(a, b, cv::NORM_INF);
}

// Frame t of the ray caster's trucking shot, with its light (any light: the bits are
// compared, not the values).
GBuffer shot_frame(const raycast::Scene& scene, int t) {
  GBuffer g = raycast::render_gbuffer(scene, raycast::truck_shot_camera(t, 203, 97), 0);
  g.lighting = g.albedo;
  return g;
}

TEST(Simd, EveryInstructionSetGivesTheSameBits) {
  const GBuffer g = raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(203, 97), 0);
  const Environment sky = Environment::sky(SkyGradient{});
  // A frame of a shot with the frames on either side as views (the multi-view passes:
  // occupancy walk, decided bins, point verdicts, the guard band and its senders' light).
  const raycast::Scene shot = raycast::truck_shot_scene();
  const GBuffer middle = shot_frame(shot, 3), before = shot_frame(shot, 1), after = shot_frame(shot, 5);
  std::vector<DepthView> views{{before.camera, before.depth_view, "f1"}, {after.camera, after.depth_view, "f5"}};
  for (auto [view, frame] : {std::pair{&views[0], &before}, std::pair{&views[1], &after}}) {
    view->albedo = frame->albedo;
    view->lighting = frame->lighting;
  }
  // Every instruction set this build and CPU run (AVX-512, AVX2 and the baseline on an
  // AVX-512 machine) against the baseline.
  const std::string chosen = simd_target();
  const std::vector<std::string> targets = simd_targets_runnable();
  ASSERT_FALSE(targets.empty());
  EXPECT_EQ(targets.back(), simd_baseline_target());
  std::vector<std::array<Terms, 2>> on(targets.size());
  for (size_t t = 0; t < targets.size(); ++t) {
    ASSERT_TRUE(use_simd_target(targets[t])) << targets[t];
    EXPECT_EQ(simd_target(), targets[t]);
    on[t] = {all_terms(g, sky), all_terms(middle, sky, views)};
  }
  ASSERT_TRUE(use_simd_target(chosen));
  const std::array<Terms, 2>& on_baseline = on.back();
  ASSERT_EQ(on[0][1].terms.views.size(), 2u);
  EXPECT_TRUE(on[0][1].terms.views[0].used && on[0][1].terms.views[1].used);
  for (size_t t = 0; t + 1 < targets.size(); ++t)
    for (int with_views : {0, 1}) {
      const Terms& a = on[t][size_t(with_views)];
      const Terms& b = on_baseline[size_t(with_views)];
      const std::string what = targets[t] + (with_views ? " with views" : "");
      EXPECT_LT(cv::mean(a.terms.ao.ao)[0], 0.99);  // something is occluded
      EXPECT_EQ(differing(a.terms.ao.ao, b.terms.ao.ao), 0.0) << what;
      EXPECT_EQ(differing(a.terms.ao.bent_normal_view, b.terms.ao.bent_normal_view), 0.0) << what;
      EXPECT_EQ(differing(a.terms.ssdo.direct, b.terms.ssdo.direct), 0.0) << what;
      EXPECT_EQ(differing(a.terms.ssdo.indirect, b.terms.ssdo.indirect), 0.0) << what;
      EXPECT_EQ(differing(a.terms.confidence, b.terms.confidence), 0.0) << what;
      EXPECT_EQ(differing(a.normals, b.normals), 0.0) << what;
      EXPECT_EQ(differing(a.denoised, b.denoised), 0.0) << what;
      EXPECT_EQ(differing(a.blurred, b.blurred), 0.0) << what;
    }
  // The views change the terms (else the comparison above would not reach their passes).
  const Terms alone = all_terms(middle, sky);
  EXPECT_GT(differing(alone.terms.ao.ao, on[0][1].terms.ao.ao), 0.0);
  EXPECT_GT(differing(alone.terms.ssdo.indirect, on[0][1].terms.ssdo.indirect), 0.0);
  EXPECT_GT(differing(alone.terms.confidence, on[0][1].terms.confidence), 0.0);
}

// The temporal filter over a neighbour in which two boxes moved (so that every pass of the
// search for changed surroundings runs, kernels/temporal_change.h): the changed pixels and
// the filtered terms are the same bits on every instruction set.
TEST(Simd, TheTemporalFilterGivesTheSameBitsOnEveryInstructionSet) {
  raycast::Scene moved = raycast::truck_shot_scene();
  for (const size_t i : {1, 6}) moved.boxes[i].centre_world.x += 0.3f;  // two boxes in the picture
  const GBuffer g = shot_frame(raycast::truck_shot_scene(), 3), u = shot_frame(moved, 4);
  cv::Mat ao_g(g.depth_view.size(), CV_32FC1), ao_u(u.depth_view.size(), CV_32FC1);
  cv::Mat light_g(g.depth_view.size(), CV_32FC3), light_u(u.depth_view.size(), CV_32FC3);
  cv::RNG rng(7);
  for (cv::Mat* m : {&ao_g, &ao_u, &light_g, &light_u}) rng.fill(*m, cv::RNG::UNIFORM, 0.0f, 1.0f);
  const std::vector<const cv::Mat*> terms_g{&ao_g, &light_g}, terms_u{&ao_u, &light_u};
  const TemporalFrame frame{g.camera, g.depth_view, g.normal_view, g.mask, terms_g};
  const std::vector<TemporalFrame> neighbours{{u.camera, u.depth_view, u.normal_view, u.mask, terms_u}};
  const std::string chosen = simd_target();
  const std::vector<std::string> targets = simd_targets_runnable();
  TemporalSettings settings;
  settings.radius_world = 0.3f;  // the terms' reach: a part of the picture changes, not all
  struct Filtered {
    cv::Mat changed, ao, light;
    int64_t changed_px = -1;
  };
  std::vector<Filtered> on(targets.size());
  for (size_t t = 0; t < targets.size(); ++t) {
    ASSERT_TRUE(use_simd_target(targets[t])) << targets[t];
    Filtered& f = on[t];
    f.changed = changed_surroundings(frame, neighbours[0], settings, f.changed_px, 2);
    std::array<cv::Mat*, 2> dsts{&f.ao, &f.light};
    const std::vector<TemporalUse> uses = filter_temporal(frame, neighbours, settings, dsts, {}, 2);
    ASSERT_TRUE(uses[0].used) << targets[t];
    EXPECT_EQ(uses[0].changed_px, f.changed_px) << targets[t];
  }
  ASSERT_TRUE(use_simd_target(chosen));
  const Filtered& baseline = on.back();
  EXPECT_GT(baseline.changed_px, 100);
  EXPECT_LT(baseline.changed_px, g.depth_view.total() / 2);
  for (size_t t = 0; t + 1 < targets.size(); ++t) {
    EXPECT_EQ(on[t].changed_px, baseline.changed_px) << targets[t];
    EXPECT_EQ(differing(on[t].changed, baseline.changed), 0.0) << targets[t];
    EXPECT_EQ(differing(on[t].ao, baseline.ao), 0.0) << targets[t];
    EXPECT_EQ(differing(on[t].light, baseline.light), 0.0) << targets[t];
  }
}

TEST(Simd, TheEnvironmentNamesAnInstructionSetInAnyCase) {
  const std::string chosen = simd_target();
  std::string error;
  std::string lower = simd_baseline_target();
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  EXPECT_TRUE(apply_simd_choice(lower.c_str(), error)) << error;
  EXPECT_EQ(simd_target(), simd_baseline_target());
  EXPECT_FALSE(apply_simd_choice("avx9", error));
  EXPECT_NE(error.find("SSDO_SIMD='avx9'"), std::string::npos) << error;
  EXPECT_NE(error.find(simd_baseline_target()), std::string::npos) << error;  // the choices are listed
  EXPECT_EQ(simd_target(), simd_baseline_target());  // a refused name changes nothing
  EXPECT_TRUE(apply_simd_choice("best", error));
  EXPECT_EQ(simd_target(), simd_targets_runnable().front());
  ASSERT_TRUE(use_simd_target(chosen));
}

// 64-bit FNV-1a of an image's samples, row by row (the bytes of its pixels only).
uint64_t digest(const cv::Mat& m) {
  uint64_t h = 14695981039346656037ull;
  const size_t row_bytes = size_t(m.cols) * m.elemSize();
  for (int y = 0; y < m.rows; ++y)
    for (size_t i = 0; i < row_bytes; ++i) h = (h ^ m.ptr<uint8_t>(y)[i]) * 1099511628211ull;
  return h;
}

// The terms are the same bits on one thread as on several (the rows' split never changes a
// value). The digests are printed ("digest <term> <hex>") so that another machine's run, e.g.
// the Arm build's (scripts/test-aarch64.sh), can be compared with this one's.
TEST(Simd, SameBitsOnAnyThreadCount) {
  const GBuffer g = raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(203, 97), 0);
  const Environment sky = Environment::sky(SkyGradient{});
  const Terms one = all_terms(g, sky, {}, 1), two = all_terms(g, sky, {}, 2), three = all_terms(g, sky, {}, 3);
  auto term_images = [](const Terms& t) {
    return std::vector<std::pair<std::string, cv::Mat>>{{"ao", t.terms.ao.ao},
                                                        {"bent_normal", t.terms.ao.bent_normal_view},
                                                        {"ssdo_direct", t.terms.ssdo.direct},
                                                        {"ssdo_indirect", t.terms.ssdo.indirect},
                                                        {"confidence", t.terms.confidence},
                                                        {"normals", t.normals},
                                                        {"ao_denoised", t.denoised},
                                                        {"indirect_blurred", t.blurred}};
  };
  const auto a = term_images(one), b = term_images(two), c = term_images(three);
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_FALSE(a[i].second.empty()) << a[i].first;
    EXPECT_EQ(differing(a[i].second, b[i].second), 0.0) << a[i].first << ": 1 against 2 threads";
    EXPECT_EQ(differing(a[i].second, c[i].second), 0.0) << a[i].first << ": 1 against 3 threads";
    std::printf("digest %s %016llx\n", a[i].first.c_str(), static_cast<unsigned long long>(digest(a[i].second)));
  }
}

}  // namespace
}  // namespace ssdo
