// The reference ray caster against closed forms: G-buffer geometry, AO of a corner, of a
// plane under a sphere and of an open plane, and the direct / one-bounce light terms.
#include "tests/support/raycast.h"

#include <cmath>

#include <gtest/gtest.h>

namespace ssdo::raycast {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kPi = 3.14159265358979f;

// Mean and max of |img - value| over the mask's foreground; also counts the pixels.
struct ErrorStats {
  double mean_abs = 0.0, max_abs = 0.0;
  int count = 0;
};
ErrorStats error_vs_constant(const cv::Mat& img, const cv::Mat& mask, float value) {
  ErrorStats e;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const double d = std::abs(double(img.at<float>(y, x)) - value);
      e.mean_abs += d;
      e.max_abs = std::max(e.max_abs, d);
      ++e.count;
    }
  if (e.count) e.mean_abs /= e.count;
  return e;
}

bool bitwise_equal(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() &&
         std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

// Cosine-weighted open fraction at a floor point a distance d from an infinite wall, ray
// limit R: the wall blocks the projected-disk segment {u < -d/R} (see corner_scene()).
double corner_ao_closed_form(double d, double radius) {
  const double a = std::min(d / radius, 1.0);
  return 1.0 - (std::acos(a) - a * std::sqrt(1.0 - a * a)) / kPi;
}

TEST(Raycast, LookAtIsRigidAndCentresTheTarget) {
  const Camera c = look_at({3.0f, -2.0f, 1.5f}, {0.5f, 1.0f, 0.2f}, {0, 0, 1}, 160, 90, 60.0f);
  const glm::mat4 id = c.world_to_view * c.view_to_world;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) EXPECT_NEAR(id[i][j], i == j ? 1.0f : 0.0f, 1e-5f);
  const glm::vec2 px = c.pixel_from_view(c.view_from_world_point({0.5f, 1.0f, 0.2f}));
  EXPECT_NEAR(px.x, 80.0f, 1e-3f);
  EXPECT_NEAR(px.y, 45.0f, 1e-3f);
  // World up projects upwards (smaller row) in the image.
  const glm::vec2 above = c.pixel_from_view(c.view_from_world_point({0.5f, 1.0f, 0.7f}));
  EXPECT_LT(above.y, px.y - 1.0f);
}

TEST(Raycast, GBufferOfTheCornerLiesOnItsPlanes) {
  const Scene scene = corner_scene();
  const Camera cam = corner_camera();
  const GBuffer g = render_gbuffer(scene, cam, 1);
  int floor = 0, wall = 0;
  for (int y = 0; y < g.height_px(); ++y)
    for (int x = 0; x < g.width_px(); ++x) {
      ASSERT_EQ(g.mask.at<uint8_t>(y, x), 255) << "the corner fills the frame";
      const cv::Vec3f pv = g.position_view.at<cv::Vec3f>(y, x);
      const cv::Vec3f nv = g.normal_view.at<cv::Vec3f>(y, x);
      const glm::vec3 p_view(pv[0], pv[1], pv[2]), n_view(nv[0], nv[1], nv[2]);
      EXPECT_FLOAT_EQ(g.depth_view.at<float>(y, x), -p_view.z);
      EXPECT_NEAR(glm::length(n_view), 1.0f, 1e-5f);
      EXPECT_LT(glm::dot(n_view, p_view), 0.0f) << "normal faces the camera";
      const glm::vec2 back = cam.pixel_from_view(p_view);
      EXPECT_NEAR(back.x, x + 0.5f, 1e-3f);
      EXPECT_NEAR(back.y, y + 0.5f, 1e-3f);
      const glm::vec3 p = glm::vec3(cam.view_to_world * glm::vec4(p_view, 1.0f));
      const glm::vec3 n = cam.world_from_view_direction(n_view);
      if (n.z > 0.99f) {
        EXPECT_NEAR(p.z, 0.0f, 1e-5f);
        ++floor;
      } else {
        EXPECT_GT(n.x, 0.99f);
        EXPECT_NEAR(p.x, 0.0f, 1e-5f);
        ++wall;
      }
    }
  EXPECT_GT(floor, 1000);
  EXPECT_GT(wall, 1000);
}

TEST(Raycast, BackgroundIsMaskedWithInfiniteDepth) {
  const GBuffer g = render_gbuffer(floating_scene(),
                                   look_at({0, -3, 1}, {0, -10, 1}, {0, 0, 1}, 32, 18, 60.0f), 1);
  EXPECT_EQ(cv::countNonZero(g.mask), 0);
  EXPECT_TRUE(std::isinf(g.depth_view.at<float>(5, 5)));
  const cv::Mat ao = reference_ao(floating_scene(), g, 1.0f, 16, 0, 1);
  EXPECT_EQ(cv::countNonZero(ao != 1.0f), 0);
}

// A floor point has AO 0.5 at any distance from an infinite wall when the radius is
// unlimited, down to 1e-6 from the corner line (a point exactly on the wall plane is the
// origin of its own surface there: hits at t = 0 are excluded); with radius R the closed form
// of corner_ao_closed_form holds.
TEST(Raycast, CornerAoMatchesClosedForm) {
  const Scene scene = corner_scene();
  constexpr int kSamples = 4096;
  const glm::vec3 up(0, 0, 1);
  for (float d : {1e-6f, 1e-3f, 0.2f, 1.0f, 5.0f}) {
    const float ao = ao_at_point(scene, {d, 0.3f, 0.0f}, up, kInf, kSamples, 0.31f, 0.77f);
    EXPECT_NEAR(ao, 0.5f, 2e-3f) << "d = " << d;
  }
  for (float d : {0.05f, 0.3f, 0.7f}) {
    const float ao = ao_at_point(scene, {d, 0.0f, 0.0f}, up, 1.0f, kSamples, 0.13f, 0.52f);
    EXPECT_NEAR(ao, corner_ao_closed_form(d, 1.0), 3e-3) << "d = " << d;
  }
  // Image version: every pixel of the frame sees AO 0.5 (floor and wall alike).
  const GBuffer g = render_gbuffer(scene, corner_camera(), 2);
  const cv::Mat ao = reference_ao(scene, g, kInf, 256, 7, 2);
  const ErrorStats e = error_vs_constant(ao, g.mask, 0.5f);
  EXPECT_EQ(e.count, 160 * 90);
  EXPECT_LT(e.mean_abs, 5e-3);
  EXPECT_LT(e.max_abs, 0.03);
}

// Plane point below a sphere of radius R centred at height h: the sphere subtends a cone
// of half-angle asin(R/h), whose cosine-weighted fraction is
// (1/pi) \int_0^{2pi} \int_0^{asin(R/h)} cos sin dtheta dphi = sin^2 = (R/h)^2.
TEST(Raycast, SphereOverPlaneAoMatchesClosedForm) {
  constexpr int kSamples = 4096;
  for (auto [r, h] : {std::pair{0.5f, 1.0f}, std::pair{0.3f, 1.5f}, std::pair{0.9f, 1.0f}}) {
    const Scene scene = sphere_over_plane(r, h);
    const double expected = 1.0 - double(r * r) / double(h * h);
    // Radius h already covers every ray that hits the sphere (first hit <= sqrt(h^2-R^2)).
    for (float radius : {kInf, h}) {
      const float ao = ao_at_point(scene, {0, 0, 0}, {0, 0, 1}, radius, kSamples, 0.4f, 0.9f);
      EXPECT_NEAR(ao, expected, 3e-3) << "R " << r << " h " << h << " radius " << radius;
    }
  }
  // Image version: the pixel nearest the foot point.
  const float r = 0.5f, h = 1.0f;
  const Scene scene = sphere_over_plane(r, h);
  const Camera cam = sphere_over_plane_camera(r, h);
  const GBuffer g = render_gbuffer(scene, cam, 2);
  const glm::vec2 foot = cam.pixel_from_view(cam.view_from_world_point({0, 0, 0}));
  const int fx = int(foot.x), fy = int(foot.y);
  ASSERT_TRUE(fx >= 0 && fx < 160 && fy >= 0 && fy < 90);
  ASSERT_EQ(g.mask.at<uint8_t>(fy, fx), 255);
  const cv::Vec3f n = g.normal_view.at<cv::Vec3f>(fy, fx);
  EXPECT_GT(cam.world_from_view_direction({n[0], n[1], n[2]}).z, 0.999f) << "foot is on the floor";
  const cv::Mat ao = reference_ao(scene, g, kInf, 1024, 3, 2);
  // The pixel centre is within ~0.02 units of the foot, where AO changes by < 0.01.
  EXPECT_NEAR(ao.at<float>(fy, fx), 0.75f, 0.015f);
}

// An open plane has AO exactly 1 at any orientation and view, grazing ones included.
TEST(Raycast, OpenPlaneAoIsExactlyOne) {
  for (glm::vec3 n : {glm::vec3(0, 0, 1), glm::normalize(glm::vec3(1, 2, 3)),
                      glm::normalize(glm::vec3(-0.3f, 0.9f, -0.2f)), glm::vec3(0, -1, 0)}) {
    for (float elevation : {90.0f, 30.0f, 3.0f, 0.5f}) {
      const Scene scene = open_plane(n);
      const GBuffer g = render_gbuffer(scene, open_plane_camera(n, elevation), 2);
      ASSERT_GT(cv::countNonZero(g.mask), 160 * 90 / 3) << "elevation " << elevation;
      for (float radius : {1.0f, kInf}) {
        const cv::Mat ao = reference_ao(scene, g, radius, 64, 1, 2);
        EXPECT_EQ(cv::countNonZero(ao != 1.0f), 0) << "elevation " << elevation;
      }
    }
  }
}

TEST(Raycast, DirectLightMatchesClosedForms) {
  const EnvironmentRadiance white = uniform_environment(glm::vec3(1.0f));
  // Open plane: direct exactly 1, indirect exactly 0 (every ray escapes).
  {
    const glm::vec3 n = glm::normalize(glm::vec3(1, -1, 2));
    const Scene scene = open_plane(n);
    const GBuffer g = render_gbuffer(scene, open_plane_camera(n, 20.0f), 2);
    const LightReference ref = reference_light(scene, g, white, kInf, 32, 5, 2);
    for (int y = 0; y < g.height_px(); ++y)
      for (int x = 0; x < g.width_px(); ++x) {
        if (!g.mask.at<uint8_t>(y, x)) continue;
        ASSERT_EQ(ref.direct.at<cv::Vec3f>(y, x), cv::Vec3f(1, 1, 1));
        ASSERT_EQ(ref.indirect.at<cv::Vec3f>(y, x), cv::Vec3f(0, 0, 0));
      }
  }
  // Corner: direct 0.5 (half the cosine lobe sees the sky); indirect = albedo 0.8 times the
  // wall's own direct 0.5 over the blocked half: 0.5 * 0.8 * 0.5 = 0.2.
  {
    const Scene scene = corner_scene();
    const LightSample s =
        light_at_point(scene, {0.5f, 0, 0}, {0, 0, 1}, white, kInf, 1 << 14, 0.2f, 0.6f, 9);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(s.direct[c], 0.5f, 2e-3f);
      EXPECT_NEAR(s.indirect[c], 0.2f, 0.01f);
    }
  }
}

// Colour bleeding: a white floor next to a red wall under a white sky picks up red light
// near the wall and none far from it.
TEST(Raycast, IndirectLightBleedsWallColourOntoTheFloor) {
  const Scene scene = red_wall_scene();
  const EnvironmentRadiance white = uniform_environment(glm::vec3(1.0f));
  const LightSample near =
      light_at_point(scene, {0.1f, 0, 0}, {0, 0, 1}, white, kInf, 4096, 0.5f, 0.5f, 1);
  EXPECT_GT(near.indirect.x, 0.1f);
  EXPECT_GT(near.indirect.x, 5.0f * near.indirect.y);
  EXPECT_GT(near.indirect.x, 5.0f * near.indirect.z);
  EXPECT_LT(near.direct.x, 0.75f) << "the wall shadows the sky";
  const LightSample far =
      light_at_point(scene, {40.0f, 0, 0}, {0, 0, 1}, white, kInf, 4096, 0.5f, 0.5f, 1);
  EXPECT_LT(far.indirect.x, 2e-3f);
  EXPECT_GT(far.direct.x, 0.998f);
  // Image version: the floor pixels nearest the wall are red-tinted on average.
  const Camera cam = red_wall_camera();
  const GBuffer g = render_gbuffer(scene, cam, 2);
  const LightReference ref = reference_light(scene, g, white, kInf, 256, 2, 2);
  double r = 0, gsum = 0;
  int n = 0;
  for (int y = 0; y < g.height_px(); ++y)
    for (int x = 0; x < g.width_px(); ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f pv = g.position_view.at<cv::Vec3f>(y, x);
      const glm::vec3 p = glm::vec3(cam.view_to_world * glm::vec4(pv[0], pv[1], pv[2], 1.0f));
      if (std::abs(p.z) > 1e-3f || p.x > 0.3f || std::abs(p.y) > 2.0f) continue;  // floor near wall
      const cv::Vec3f ind = ref.indirect.at<cv::Vec3f>(y, x);
      r += ind[0];
      gsum += ind[1];
      ++n;
    }
  ASSERT_GT(n, 50);
  EXPECT_GT(r / n, 0.08);
  EXPECT_GT(r, 5.0 * gsum);
}

TEST(Raycast, SameBytesForOneAndTwoThreads) {
  const Scene scene = cornell_scene();
  const GBuffer g1 = render_gbuffer(scene, cornell_camera(), 1);
  const GBuffer g2 = render_gbuffer(scene, cornell_camera(), 2);
  EXPECT_TRUE(bitwise_equal(g1.depth_view, g2.depth_view));
  EXPECT_TRUE(bitwise_equal(g1.normal_view, g2.normal_view));
  EXPECT_TRUE(bitwise_equal(g1.albedo, g2.albedo));
  EXPECT_TRUE(bitwise_equal(reference_ao(scene, g1, 1.0f, 64, 11, 1),
                            reference_ao(scene, g1, 1.0f, 64, 11, 2)));
  const EnvironmentRadiance sky = gradient_sky_environment();
  const LightReference a = reference_light(scene, g1, sky, kInf, 16, 11, 1);
  const LightReference b = reference_light(scene, g1, sky, kInf, 16, 11, 2);
  EXPECT_TRUE(bitwise_equal(a.direct, b.direct));
  EXPECT_TRUE(bitwise_equal(a.indirect, b.indirect));
}

TEST(Raycast, CornellFrameHasPlausibleAo) {
  const Scene scene = cornell_scene();
  const GBuffer g = render_gbuffer(scene, cornell_camera(), 2);
  EXPECT_GT(cv::countNonZero(g.mask), 160 * 90 * 9 / 10) << "the room fills most of the frame";
  const cv::Mat ao = reference_ao(scene, g, 1.0f, 256, 0, 2);
  double lo, hi;
  cv::minMaxLoc(ao, &lo, &hi);
  EXPECT_LT(lo, 0.5);
  EXPECT_EQ(hi, 1.0);
  const double mean = cv::mean(ao)[0];
  EXPECT_GT(mean, 0.6);
  EXPECT_LT(mean, 0.95);
}

}  // namespace
}  // namespace ssdo::raycast
