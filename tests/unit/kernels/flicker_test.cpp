// The flicker metric (kernels/metrics.h): the reprojected frame-to-frame change of an
// estimate over the surfaces two frames share.
#include <gtest/gtest.h>

#include "kernels/metrics.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

constexpr int kWidth = 80, kHeight = 45;

Camera camera_at(float eye_x) {
  return raycast::look_at({eye_x, -3.0f, 2.0f}, {eye_x, 2.0f, 0.5f}, {0, 0, 1}, kWidth, kHeight, 60.0f);
}

// A floor and a box on it.
raycast::Scene box_on_floor() {
  raycast::Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(0, 0, 1), glm::vec3(0.8f)});
  s.boxes.push_back({glm::vec3(0.0f, 1.0f, 0.5f), glm::vec3(0.5f), glm::mat3(1.0f), glm::vec3(0.8f)});
  return s;
}

// x of the world point each pixel sees: a value every frame agrees on.
cv::Mat world_x(const GBuffer& g) {
  cv::Mat v(g.depth_view.size(), CV_32FC1, cv::Scalar(0.0f));
  for (int y = 0; y < v.rows; ++y)
    for (int x = 0; x < v.cols; ++x)
      if (g.mask.at<uint8_t>(y, x))
        v.at<float>(y, x) = (g.camera.view_to_world *
                             glm::vec4(g.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, g.depth_view.at<float>(y, x)),
                                       1.0f)).x;
  return v;
}

TEST(Flicker, ConstantChangeOnAStaticCamera) {
  const GBuffer g = raycast::render_gbuffer(box_on_floor(), camera_at(0.0f), 1);
  const cv::Mat reference(g.depth_view.size(), CV_32FC1, cv::Scalar(0.5f));
  const cv::Mat a(g.depth_view.size(), CV_32FC1, cv::Scalar(0.3f)), b(g.depth_view.size(), CV_32FC1, cv::Scalar(0.4f));
  FlickerAccumulator flicker;
  flicker.add({a, reference, g.depth_view, g.normal_view, g.mask, g.camera},
              {b, reference, g.depth_view, g.normal_view, g.mask, g.camera});
  EXPECT_EQ(flicker.pixels(), cv::countNonZero(g.mask));
  EXPECT_NEAR(flicker.mean_change(), 0.1, 1e-6);
  EXPECT_EQ(flicker.reference_change(), 0.0);
}

TEST(Flicker, ReferenceChangesAreLeftOut) {
  const GBuffer g = raycast::render_gbuffer(box_on_floor(), camera_at(0.0f), 1);
  const cv::Mat a(g.depth_view.size(), CV_32FC1, cv::Scalar(0.3f)), b(g.depth_view.size(), CV_32FC1, cv::Scalar(0.4f));
  const cv::Mat reference_a(g.depth_view.size(), CV_32FC1, cv::Scalar(0.5f));
  cv::Mat reference_b = reference_a.clone();
  reference_b.rowRange(0, kHeight / 2).setTo(0.6f);  // the top half's truth changed
  FlickerAccumulator flicker;
  flicker.add({a, reference_a, g.depth_view, g.normal_view, g.mask, g.camera},
              {b, reference_b, g.depth_view, g.normal_view, g.mask, g.camera});
  EXPECT_EQ(flicker.pixels(), cv::countNonZero(g.mask.rowRange(kHeight / 2, kHeight)));
}

TEST(Flicker, MovingCameraSameSurfacesOnly) {
  // The camera trucks: an estimate that is a function of the world point does not flicker
  // (up to its change across the half texel between a point and the nearest texel centre);
  // one fixed to the screen does, on the pixels both frames see.
  const raycast::Scene scene = box_on_floor();
  const GBuffer g0 = raycast::render_gbuffer(scene, camera_at(0.0f), 1);
  const GBuffer g1 = raycast::render_gbuffer(scene, camera_at(0.2f), 1);
  const cv::Mat x0 = world_x(g0), x1 = world_x(g1);
  FlickerAccumulator world, screen;
  world.add({x0, x0, g0.depth_view, g0.normal_view, g0.mask, g0.camera},
            {x1, x1, g1.depth_view, g1.normal_view, g1.mask, g1.camera});
  // Left out: what leaves the picture, and the far floor, whose x changes by more than
  // reference_change_max from one texel to the next.
  EXPECT_GT(world.pixels(), cv::countNonZero(g0.mask) * 7 / 10);
  EXPECT_LT(world.mean_change(), 0.02);
  cv::Mat columns(g0.depth_view.size(), CV_32FC1);
  for (int x = 0; x < kWidth; ++x) columns.col(x).setTo(float(x) / kWidth);
  screen.add({columns, x0, g0.depth_view, g0.normal_view, g0.mask, g0.camera},
             {columns, x1, g1.depth_view, g1.normal_view, g1.mask, g1.camera});
  EXPECT_GT(screen.mean_change(), 0.025);  // ~3 pixels of shift x 1/80 per pixel
}

}  // namespace
}  // namespace ssdo
