// Camera: pixel <-> view round trips, field of view, and from_fov_x against the projection
// Blender wrote for the shared cornell frame.
#include "core/camera.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace ssdo {
namespace {

// A projection with lens shift and non-square pixels: the general case the kernels keep.
Camera shifted_camera() {
  Camera c = Camera::from_fov_x(320, 200, 70.0f, 0.1f, 100.0f);
  c.view_to_clip[2][0] = 0.12f;   // horizontal lens shift (x_clip += 0.12 z)
  c.view_to_clip[2][1] = -0.05f;  // vertical lens shift
  c.view_to_clip[1][1] *= 1.1f;   // non-square pixels
  return c;
}

TEST(Camera, PixelDepthViewRoundTrip) {
  for (const Camera& cam : {Camera::from_fov_x(640, 360, 65.0f), shifted_camera()}) {
    for (const glm::vec2 px : {glm::vec2(0.5f, 0.5f), glm::vec2(320.0f, 180.0f), glm::vec2(17.25f, 300.75f),
                               glm::vec2(319.5f, 199.5f)}) {
      for (const float depth : {0.2f, 3.0f, 250.0f}) {
        const glm::vec3 p = cam.view_from_pixel_depth(px, depth);
        EXPECT_FLOAT_EQ(p.z, -depth);
        const glm::vec2 back = cam.pixel_from_view(p);
        EXPECT_NEAR(back.x, px.x, 1e-3f * std::max(1.0f, depth / 10.0f));
        EXPECT_NEAR(back.y, px.y, 1e-3f * std::max(1.0f, depth / 10.0f));
      }
    }
  }
}

// The NDC convention (core/camera.h): the image's top-left corner is (-1, +1), its
// bottom-right (+1, -1); pixel_from_ndc undoes ndc_from_pixel.
TEST(Camera, NdcOfThePixelGrid) {
  const Camera cam = Camera::from_fov_x(640, 360, 65.0f);
  EXPECT_EQ(cam.ndc_from_pixel({0.0f, 0.0f}), glm::vec2(-1.0f, 1.0f));
  EXPECT_EQ(cam.ndc_from_pixel({640.0f, 360.0f}), glm::vec2(1.0f, -1.0f));
  EXPECT_EQ(cam.ndc_from_pixel({320.0f, 180.0f}), glm::vec2(0.0f, 0.0f));
  EXPECT_EQ(cam.ndc_from_pixel({480.0f, 90.0f}), glm::vec2(0.5f, 0.5f));
  for (const glm::vec2 px : {glm::vec2(0.5f, 0.5f), glm::vec2(17.25f, 300.75f), glm::vec2(639.5f, 359.5f)}) {
    const glm::vec2 back = cam.pixel_from_ndc(cam.ndc_from_pixel(px));
    EXPECT_NEAR(back.x, px.x, 1e-4f);
    EXPECT_NEAR(back.y, px.y, 1e-4f);
  }
}

TEST(Camera, PointsBehindTheEyeDoNotProject) {
  const Camera cam = Camera::from_fov_x(64, 64, 90.0f);
  EXPECT_TRUE(std::isnan(cam.pixel_from_view({0.0f, 0.0f, 1.0f}).x));
}

TEST(Camera, FovAndCentreRay) {
  const Camera cam = Camera::from_fov_x(400, 200, 90.0f);
  EXPECT_NEAR(cam.fov_x_deg(), 90.0f, 1e-4f);
  EXPECT_NEAR(cam.fov_y_deg(), 2.0f * glm::degrees(std::atan(0.5f)), 1e-4f);
  const glm::vec3 d = cam.view_ray_direction({200.0f, 100.0f});
  EXPECT_NEAR(d.x, 0.0f, 1e-6f);
  EXPECT_NEAR(d.y, 0.0f, 1e-6f);
  EXPECT_NEAR(d.z, -1.0f, 1e-6f);
  // The right edge of the image is 45 degrees off axis; the top row is +y.
  const glm::vec3 right = cam.view_ray_direction({400.0f, 100.0f});
  EXPECT_NEAR(glm::degrees(std::atan2(right.x, -right.z)), 45.0f, 1e-3f);
  EXPECT_GT(cam.view_ray_direction({200.0f, 0.0f}).y, 0.0f);
  // Pixels per unit at depth d: W / (2 d tan(fov/2)).
  EXPECT_NEAR(cam.pixels_per_unit(2.0f).x, 400.0f / (2.0f * 2.0f), 1e-3f);
}

TEST(Camera, FromFovXMatchesTheCornellSidecarProjection) {
  const std::filesystem::path path =
      std::filesystem::path(SSDO_SHARED_DIR) / "gbuffers" / "cornell.camera.json";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not found: " << path;
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in);
  const Camera cam = Camera::from_fov_x(j["width"].get<int>(), j["height"].get<int>(),
                                        j["fov_x_deg"].get<float>(), j["clip_near"].get<float>(),
                                        j["clip_far"].get<float>());
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      EXPECT_NEAR(cam.view_to_clip[c][r], j["projection"][r][c].get<float>(), 1e-5f)
          << "row " << r << " col " << c;
}

}  // namespace
}  // namespace ssdo
