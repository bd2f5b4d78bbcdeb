// The raymarch AO oracle against the reference ray caster: exact on an open plane, close
// to the Monte-Carlo reference where the frame shows every relevant occluder, better with a
// finite thickness at depth discontinuities, and thread-count independent.
#include "kernels/ao_raymarch.h"

#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "tests/support/raycast.h"
#include "tests/support/skips.h"

namespace ssdo {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

AoSettings raymarch_settings(int directions, int steps, float radius_world, float thickness_world) {
  AoSettings s = ao_preset(AoMethod::raymarch, Preset::low);
  s.directions = directions;
  s.steps = steps;
  s.radius_world = radius_world;
  s.thickness_world = thickness_world;
  return s;
}

struct Raymarched {
  AoOutput out;
  cv::Mat confidence;
};

Raymarched raymarch(const GBuffer& g, const AoSettings& s, int nthreads = 2) {
  const AoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
  Raymarched r;
  compute_ao_raymarch(in, s, r.out, r.confidence, {}, nthreads);
  return r;
}

// Mean |a - b| over pixels where `select` is non-zero; returns the count too.
double mean_abs_diff(const cv::Mat& a, const cv::Mat& b, const cv::Mat& select, int* count) {
  double sum = 0.0;
  int n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!select.at<uint8_t>(y, x)) continue;
      sum += std::abs(double(a.at<float>(y, x)) - double(b.at<float>(y, x)));
      ++n;
    }
  if (count) *count = n;
  return n ? sum / n : 0.0;
}

bool bitwise_equal(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() &&
         std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

TEST(AoRaymarch, ComputeAoDispatchesToTheOracle) {
  const GBuffer g = raycast::render_gbuffer(raycast::corner_scene(), raycast::corner_camera(), 2);
  const AoSettings s = raymarch_settings(32, 16, 1.0f, kInf);
  const AoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
  AoOutput via_compute_ao;
  compute_ao(in, s, via_compute_ao, {}, 2);
  const Raymarched direct = raymarch(g, s);
  EXPECT_TRUE(bitwise_equal(via_compute_ao.ao, direct.out.ao));
  EXPECT_TRUE(bitwise_equal(via_compute_ao.bent_normal_view, direct.out.bent_normal_view));
}

// An open plane is open: AO exactly 1 at every pixel for head-on, oblique and grazing
// views (the tangent-plane depth reference keeps the sub-pixel depth change from
// occluding), and the bent normal is the normal up to the sampling's noise.
TEST(AoRaymarch, OpenPlaneIsExactlyOne) {
  SSDO_REFERENCE_MEASUREMENT();
  for (glm::vec3 n_world : {glm::vec3(0, 0, 1), glm::normalize(glm::vec3(1, 2, 3))}) {
    for (float elevation : {90.0f, 30.0f, 5.0f}) {
      const Camera cam = raycast::open_plane_camera(n_world, elevation, 96, 54);
      const GBuffer g = raycast::render_gbuffer(raycast::open_plane(n_world), cam, 2);
      for (float thickness : {kInf, 0.5f}) {
        const Raymarched r = raymarch(g, raymarch_settings(64, 32, 1.0f, thickness));
        EXPECT_EQ(cv::countNonZero(r.out.ao != 1.0f), 0)
            << "elevation " << elevation << " thickness " << thickness;
      }
      const Raymarched r = raymarch(g, raymarch_settings(256, 8, 1.0f, kInf));
      const glm::vec3 n_view = glm::normalize(cam.view_from_world_direction(n_world));
      float worst = 1.0f;
      for (int y = 0; y < g.height_px(); ++y)
        for (int x = 0; x < g.width_px(); ++x) {
          if (!g.mask.at<uint8_t>(y, x)) continue;
          const cv::Vec3f b = r.out.bent_normal_view.at<cv::Vec3f>(y, x);
          worst = std::min(worst, glm::dot(glm::vec3(b[0], b[1], b[2]), n_view));
        }
      EXPECT_GT(worst, 0.995f) << "elevation " << elevation;
    }
  }
}

// The same through parallel rays: the orthographic reference depth (the view ray through a
// step is (q.x, q.y, -d); d where it meets the tap's tangent plane) keeps an open plane open
// at oblique and grazing views too.
TEST(AoRaymarch, OpenPlaneIsExactlyOneThroughAnOrthographicCamera) {
  const glm::vec3 n_world = glm::normalize(glm::vec3(1, 2, 3));
  for (float elevation : {90.0f, 30.0f, 5.0f}) {
    const Camera cam = raycast::with_parallel_rays(raycast::open_plane_camera(n_world, elevation, 96, 54), 2.0f);
    ASSERT_FALSE(cam.is_perspective());
    const GBuffer g = raycast::render_gbuffer(raycast::open_plane(n_world), cam, 2);
    ASSERT_GT(cv::countNonZero(g.mask), 96 * 54 / 4) << "elevation " << elevation;
    for (float thickness : {kInf, 0.5f}) {
      const Raymarched r = raymarch(g, raymarch_settings(64, 32, 1.0f, thickness));
      EXPECT_EQ(cv::countNonZero((r.out.ao != 1.0f) & g.mask), 0)
          << "elevation " << elevation << " thickness " << thickness;
    }
  }
}

// The corner seen from the front and from far enough that most occluders within the
// radius are on screen: where every step landed on screen (confidence 1), the oracle
// matches the ray-traced reference up to the two estimators' noise.
TEST(AoRaymarch, CornerMatchesReferenceWhereEverythingIsVisible) {
  SSDO_REFERENCE_MEASUREMENT();
  const raycast::Scene scene = raycast::corner_scene();
  const Camera cam = raycast::look_at({5.0f, 0.0f, 2.2f}, {0.0f, 0.0f, 0.3f}, {0, 0, 1}, 160, 90, 70.0f);
  const GBuffer g = raycast::render_gbuffer(scene, cam, 2);
  const float radius = 1.0f;
  const cv::Mat reference = raycast::reference_ao(scene, g, radius, 512, 3, 2);
  const Raymarched r = raymarch(g, raymarch_settings(256, 64, radius, kInf));
  const cv::Mat visible = (r.confidence == 1.0f) & g.mask;
  int n = 0;
  const double err = mean_abs_diff(r.out.ao, reference, visible, &n);
  EXPECT_GT(n, 160 * 90 / 3);
  EXPECT_LT(err, 0.006);
  // Mean AO over those pixels agrees too (no systematic bias).
  EXPECT_NEAR(cv::mean(r.out.ao, visible)[0], cv::mean(reference, visible)[0], 0.005);
  // Occlusion is real: the darkest visible pixels (next to the corner line) are near the
  // closed form's limit 0.5.
  double lo;
  cv::minMaxLoc(r.out.ao, &lo, nullptr, nullptr, nullptr, visible);
  EXPECT_LT(lo, 0.6);
}

TEST(AoRaymarch, SameBytesForOneAndTwoThreads) {
  const GBuffer g = raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(), 2);
  const AoSettings s = raymarch_settings(64, 24, 1.0f, 0.5f);
  const Raymarched a = raymarch(g, s, 1);
  const Raymarched b = raymarch(g, s, 2);
  EXPECT_TRUE(bitwise_equal(a.out.ao, b.out.ao));
  EXPECT_TRUE(bitwise_equal(a.out.bent_normal_view, b.out.bent_normal_view));
  EXPECT_TRUE(bitwise_equal(a.confidence, b.confidence));
  // A region of interest writes the same values as the full frame, and only there.
  const AoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
  AoOutput part;
  part.ao = cv::Mat(g.depth_view.size(), CV_32FC1, cv::Scalar(-1.0f));
  const cv::Rect roi(30, 20, 50, 31);
  compute_ao(in, s, part, roi, 2);
  EXPECT_TRUE(bitwise_equal(part.ao(roi).clone(), a.out.ao(roi).clone()));
  EXPECT_EQ(cv::countNonZero(part.ao != -1.0f), roi.area());
}

// Objects floating 4-6 units in front of a back plane: as a height field (infinite
// thickness) the depth buffer makes solid walls of their silhouettes and darkens the plane
// around them; a thickness of 0.5 lets the plane's rays pass behind them, as in reality
// (the objects are far beyond the 1-unit radius).
TEST(AoRaymarch, ThicknessReducesErrorAtDepthDiscontinuities) {
  SSDO_REFERENCE_MEASUREMENT();
  const raycast::Scene scene = raycast::floating_scene();
  const GBuffer g = raycast::render_gbuffer(scene, raycast::floating_camera(), 2);
  const float radius = 1.0f;
  const cv::Mat reference = raycast::reference_ao(scene, g, radius, 256, 5, 2);
  const Raymarched height_field = raymarch(g, raymarch_settings(128, 48, radius, kInf));
  const Raymarched thick = raymarch(g, raymarch_settings(128, 48, radius, 0.5f));
  const double err_inf = mean_abs_diff(height_field.out.ao, reference, g.mask, nullptr);
  const double err_thick = mean_abs_diff(thick.out.ao, reference, g.mask, nullptr);
  EXPECT_LT(err_thick, 0.25 * err_inf);
  EXPECT_GT(err_inf, 0.04) << "the height field's halo is visible in the mean";
  EXPECT_LT(err_thick, 0.005);
  // Rays leaving the frame lower the confidence; it stays within [0, 1].
  double lo, hi;
  cv::minMaxLoc(thick.confidence, &lo, &hi);
  EXPECT_LT(lo, 0.9);
  EXPECT_GE(lo, 0.0);
  EXPECT_EQ(hi, 1.0);
}

// Background pixels: AO 1, bent normal 0, confidence 1; foreground rays that land on
// background never occlude.
TEST(AoRaymarch, BackgroundNeverOccludes) {
  // A sphere alone in the frame: its rays that leave it land on background.
  raycast::Scene scene;
  scene.spheres.push_back({glm::vec3(0.0f), 1.0f, glm::vec3(0.8f)});
  const Camera cam = raycast::look_at({0, -5, 0}, {0, 0, 0}, {0, 0, 1}, 96, 54, 50.0f);
  const GBuffer g = raycast::render_gbuffer(scene, cam, 2);
  ASSERT_GT(cv::countNonZero(g.mask), 500);
  ASSERT_LT(cv::countNonZero(g.mask), int(g.mask.total()) - 500);
  const Raymarched r = raymarch(g, raymarch_settings(64, 32, 1.0f, kInf));
  // A convex object has no occluder. Pixels facing the camera (n . v > 0.9) cannot reach
  // the space behind the sphere within the radius (the chord to the silhouette exceeds
  // 1), so they are exactly 1; near the silhouette a height field sees steps that go
  // behind the sphere as occluded, which no screen-space method can tell apart.
  int facing = 0;
  for (int y = 0; y < g.height_px(); ++y)
    for (int x = 0; x < g.width_px(); ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f n = g.normal_view.at<cv::Vec3f>(y, x), p = g.position_view.at<cv::Vec3f>(y, x);
      if (-n.dot(p) / cv::norm(p) <= 0.9) continue;
      ++facing;
      EXPECT_EQ(r.out.ao.at<float>(y, x), 1.0f) << x << ", " << y;
    }
  EXPECT_GT(facing, 200);
  EXPECT_GT(cv::mean(r.out.ao, g.mask)[0], 0.98);
  const cv::Mat background = g.mask == 0;
  EXPECT_EQ(cv::countNonZero((r.out.ao != 1.0f) & background), 0);
  EXPECT_EQ(cv::countNonZero((r.confidence != 1.0f) & background), 0);
  for (int y = 0; y < g.height_px(); ++y)
    for (int x = 0; x < g.width_px(); ++x) {
      const double len = cv::norm(r.out.bent_normal_view.at<cv::Vec3f>(y, x));
      ASSERT_NEAR(len, g.mask.at<uint8_t>(y, x) ? 1.0 : 0.0, 1e-5) << x << ", " << y;
    }
  // Near the silhouette some steps land on background: confidence below 1 there.
  double lo;
  cv::minMaxLoc(r.confidence, &lo, nullptr, nullptr, nullptr, g.mask);
  EXPECT_LT(lo, 1.0);
}

}  // namespace
}  // namespace ssdo
