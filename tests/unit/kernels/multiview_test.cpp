// Occupancy from other views (kernels/multiview.h) on ray-cast scenes with exact answers:
// the back of a thin slab seen from a second camera, a view that repeats the frame, a view
// of another scene, and the AO of a short camera move along thin posts in front of a wall.
#include <gtest/gtest.h>

#include "kernels/half_resolution.h"
#include "kernels/metrics.h"
#include "kernels/multiview.h"
#include "kernels/positions.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kWidth = 160, kHeight = 90;

// A wall at y = 3 and, 1.5 units in front of it, a slab 0.1 thick facing the camera.
raycast::Scene slab_scene() {
  raycast::Scene s;
  s.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  s.boxes.push_back({{0.0f, 1.5f, 0.0f}, {0.4f, 0.05f, 0.6f}, glm::mat3(1.0f), glm::vec3(0.8f)});
  return s;
}

Camera camera_at(float x_world) {
  return raycast::look_at({x_world, -3.0f, 0.0f}, {x_world, 3.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, kWidth, kHeight, 60.0f);
}

DepthView view_of(const raycast::Scene& scene, const Camera& camera, const std::string& name) {
  return {camera, raycast::render_gbuffer(scene, camera, 2).depth_view, name};
}

cv::Mat back_layer(const GBuffer& g, const std::vector<DepthView>& views, std::vector<ViewUse>* uses = nullptr,
                   int nthreads = 2) {
  cv::Mat back;
  const std::vector<ViewUse> u =
      occupancy_from_views({g.depth_view, g.mask, g.camera}, views, MultiViewSettings{}, back, nthreads);
  if (uses) *uses = u;
  return back;
}

// Thin posts 1.2 units in front of a wall and a floor below: alone, GTAO's assumed
// thickness (half the radius) makes each post a thick block that darkens the wall behind
// and beside it; the frames of a sideways camera move see past the posts.
raycast::Scene posts_scene() {
  raycast::Scene s;
  s.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  s.planes.push_back({{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, 1.0f}, glm::vec3(0.8f)});
  for (float x : {-1.2f, -0.4f, 0.4f, 1.2f})
    s.boxes.push_back({{x, 1.8f, 0.0f}, {0.04f, 0.04f, 1.0f}, glm::mat3(1.0f), glm::vec3(0.8f)});
  return s;
}

TEST(MultiView, CamerasOnEitherSideSeePastThinPosts) {
  const raycast::Scene scene = posts_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const cv::Mat exact = raycast::render_depth_back(scene, g.camera, 2);
  std::vector<ViewUse> uses;
  const cv::Mat back =
      back_layer(g, {view_of(scene, camera_at(-1.0f), "left"), view_of(scene, camera_at(1.0f), "right")}, &uses);
  ASSERT_EQ(uses.size(), 2u);
  for (const ViewUse& u : uses) {
    EXPECT_TRUE(u.used);
    EXPECT_GT(u.overlap, 0.8f);
    EXPECT_EQ(u.contradiction, 0.0f);
  }
  ASSERT_FALSE(back.empty());
  // Post pixels (the posts' back faces are the only finite exact back depths): the occluder
  // never ends inside the post (to the walk's resolution, reach 2 / 12 samples / 2^4
  // bisections), and on average ends well before the assumed thickness of 0.5. The side
  // cameras see the space behind a post from ~0.2 behind it (0.04 half width x distance /
  // baseline).
  const MultiViewSettings s;
  const float resolution = s.reach_world / float(s.samples) / float(1 << s.refinements);
  int posts = 0;
  double mean_thickness = 0;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const float e = exact.at<float>(y, x);
      if (!(e < kInf)) continue;
      ++posts;
      const float b = back.at<float>(y, x);
      EXPECT_GE(b, e - resolution) << x << "," << y;
      mean_thickness += double(std::min(b, 10.0f) - g.depth_view.at<float>(y, x));
    }
  ASSERT_GT(posts, 200);
  mean_thickness /= posts;
  std::printf("posts: %d pixels, mean occluder thickness %.3f (exact 0.08, assumed 0.5)\n", posts, mean_thickness);
  EXPECT_LT(mean_thickness, 0.32);
}

TEST(MultiView, AViewOfTheSameCameraChangesNothingButTheThicknessBoundary) {
  const raycast::Scene scene = slab_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const cv::Mat back = back_layer(g, {view_of(scene, camera_at(0.0f), "same")});
  ASSERT_FALSE(back.empty());
  const MultiViewSettings s;
  const float resolution = s.reach_world / float(s.samples) / float(1 << s.refinements);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      if (!g.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(back.at<float>(y, x), kInf);
        continue;
      }
      EXPECT_NEAR(back.at<float>(y, x), g.depth_view.at<float>(y, x) + s.thickness_world, resolution);
    }
}

TEST(MultiView, AViewOfAnotherSceneIsNotUsed) {
  const GBuffer g = raycast::render_gbuffer(slab_scene(), camera_at(0.0f), 2);
  raycast::Scene other;  // only a far wall: this frame's surfaces lie in its free space
  other.planes.push_back({{0.0f, 10.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  std::vector<ViewUse> uses;
  const cv::Mat back = back_layer(g, {view_of(other, camera_at(0.3f), "cut")}, &uses);
  EXPECT_FALSE(uses[0].used);
  EXPECT_GT(uses[0].contradiction, 0.5f);
  EXPECT_TRUE(back.empty());
}

TEST(MultiView, SameBytesForAnyThreadCount) {
  const raycast::Scene scene = slab_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const std::vector<DepthView> views{view_of(scene, camera_at(-0.6f), "left"), view_of(scene, camera_at(0.6f), "right")};
  const cv::Mat one = back_layer(g, views, nullptr, 1), two = back_layer(g, views, nullptr, 2);
  EXPECT_EQ(cv::norm(one, two, cv::NORM_INF), 0.0);
}

double gtao_error(const GBuffer& g, const cv::Mat& reference, const std::vector<DepthView>& views) {
  AoSettings s = ao_preset(AoMethod::gtao, Preset::high);
  cv::Mat positions;
  view_positions_from_depth(g.depth_view, g.mask, g.camera, positions);
  const TermInputs in{g.depth_view, g.normal_view, positions, g.mask, g.camera, nullptr, nullptr, nullptr, nullptr,
                      views};
  TermOutputs out;
  compute_terms(in, {&s, nullptr, nullptr}, out, {}, 2);
  return compare_images(out.ao.ao, reference, g.mask).mae;
}

TEST(MultiView, NeighbouringFramesLowerTheErrorOfThinPosts) {
  const raycast::Scene scene = posts_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const cv::Mat reference = raycast::reference_ao(scene, g, 1.0f, 256, 7, 2);
  const double alone = gtao_error(g, reference, {});
  const double with = gtao_error(g, reference, {view_of(scene, camera_at(-0.5f), "f-1"),
                                                view_of(scene, camera_at(0.5f), "f+1")});
  std::printf("thin posts: MAE alone %.4f, with 2 views %.4f\n", alone, with);
  EXPECT_LT(with, alone * 0.9);
}

}  // namespace
}  // namespace ssdo
