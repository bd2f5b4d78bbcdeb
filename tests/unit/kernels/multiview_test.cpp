// Occupancy from other views (kernels/multiview.h) on ray-cast scenes with exact answers:
// the back of a thin slab seen from a second camera, a view that repeats the frame, a view
// of another scene, and the AO of a short camera move along thin posts in front of a wall;
// the guard band of off-screen texels the views fill (its width, its camera, its depth,
// the AO it darkens, the bytes it leaves alone).
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "kernels/environment.h"
#include "kernels/half_resolution.h"
#include "kernels/metrics.h"
#include "kernels/multiview.h"
#include "kernels/positions.h"
#include "tests/support/raycast.h"

namespace ssdo::multiview_test {  // its own names in a unity batch of test files
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

TEST(MultiView, ViewsAtTheGridsDensityKeepEachBlocksNearestDepth) {
  DepthView view{camera_at(0.0f), cv::Mat(kHeight, kWidth, CV_32FC1, cv::Scalar(5.0f)), "view"};
  view.depth_view.at<float>(10, 21) = 2.0f;  // block (10, 5) of 2x2
  view.depth_view.at<float>(11, 20) = std::numeric_limits<float>::quiet_NaN();
  view.depth_view.at<float>(0, 0) = kInf;     // background in block (0, 0): a nearer pixel wins
  const std::vector<DepthView> coarse = views_at_density({&view, 1}, kWidth / 2);
  ASSERT_EQ(coarse.size(), 1u);
  EXPECT_EQ(coarse[0].camera.width_px, kWidth / 2);
  EXPECT_EQ(coarse[0].camera.height_px, kHeight / 2);
  EXPECT_EQ(coarse[0].depth_view.size(), cv::Size(kWidth / 2, kHeight / 2));
  EXPECT_EQ(coarse[0].depth_view.at<float>(5, 10), 2.0f);
  EXPECT_EQ(coarse[0].depth_view.at<float>(0, 0), 5.0f);
  EXPECT_EQ(coarse[0].depth_view.at<float>(20, 30), 5.0f);
  // The same pixel seen through both cameras: the texel's centre is the block's centre.
  const glm::vec3 p = view.camera.view_from_pixel_depth({22.0f, 12.0f}, 4.0f);
  EXPECT_NEAR(glm::length(coarse[0].camera.view_from_pixel_depth({11.0f, 6.0f}, 4.0f) - p), 0.0f, 1e-5f);
  // A view no denser than the grid is shared, not copied.
  const std::vector<DepthView> same = views_at_density({&view, 1}, kWidth);
  EXPECT_EQ(same[0].depth_view.data, view.depth_view.data);
}

TEST(MultiView, DecidedBinsAreThePointVerdictsAtTheBinCentres) {
  const raycast::Scene scene = posts_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const std::vector<DepthView> views{view_of(scene, camera_at(-0.5f), "left"), view_of(scene, camera_at(0.5f), "right")};
  const MultiViewSettings s;
  const float scale = 1.001f, bin_depth = 0.6f;
  const int bins = 3;
  const cv::Mat decided = decided_bins_behind_surfaces({g.depth_view, g.mask, g.camera}, views, s, scale, bin_depth, bins, 2);
  ASSERT_EQ(decided.type(), CV_8UC1);
  const PointVerdicts verdicts(g.camera, views, s);
  int agree = 0, set = 0, compared = 0;
  for (int y = 0; y < kHeight; y += 3)
    for (int x = 0; x < kWidth; x += 3) {
      if (!g.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(decided.at<uint8_t>(y, x), 0);
        continue;
      }
      for (int i = 0; i < bins; ++i) {
        const float d = g.depth_view.at<float>(y, x) * scale + (float(i) + 0.5f) * bin_depth;
        const bool expected = verdicts.decided(g.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, d));
        const bool got = (decided.at<uint8_t>(y, x) >> i) & 1;
        agree += got == expected;
        set += got;
        ++compared;
      }
    }
  // The same rule at the same points; the pass walks each texel's ray in affine steps, which
  // rounds a few points across a view's pixel boundary.
  EXPECT_GE(agree, compared - compared / 200);
  EXPECT_GT(set, compared / 4);       // the views decide much behind the posts and the wall
  EXPECT_LT(set, compared);           // and not everything: the wall's back is seen by none
  EXPECT_EQ(cv::countNonZero(decided_bins_behind_surfaces({g.depth_view, g.mask, g.camera}, {}, s, scale,
                                                          bin_depth, bins)),
            0);
}

double gtao_error(const GBuffer& g, const cv::Mat& reference, const std::vector<DepthView>& views,
                  ThicknessModel model) {
  AoSettings s = ao_preset(AoMethod::gtao, Preset::high);
  s.thickness_model = model;
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
  const std::vector<DepthView> views{view_of(scene, camera_at(-0.5f), "f-1"), view_of(scene, camera_at(0.5f), "f+1")};
  double alone[2], with[2];
  for (const ThicknessModel model : {ThicknessModel::constant, ThicknessModel::silhouettes}) {
    alone[int(model)] = gtao_error(g, reference, {}, model);
    with[int(model)] = gtao_error(g, reference, views, model);
    std::printf("thin posts, %s thickness: MAE alone %.4f, with 2 views %.4f\n",
                model == ThicknessModel::constant ? "constant" : "silhouettes'", alone[int(model)], with[int(model)]);
  }
  // The views see the space behind the posts that a constant thickness fills.
  EXPECT_LT(with[0], alone[0] * 0.9);
  // The silhouettes make the posts thin without views, and better than the views do: the
  // other views' intervals are constant ones (MultiViewSettings::thickness_world), which the
  // space behind the posts lies in where every view has it hidden.
  EXPECT_LT(alone[1], with[0] * 0.8);
  EXPECT_LT(with[1], alone[0]);
}

// ---- The guard band ----

TEST(GuardBand, WidenedCameraKeepsEveryPixelsRay) {
  const Camera c = camera_at(0.3f);
  // Every side alike, and each side its own (left, top, right, bottom).
  for (const BandMargins m : {BandMargins{12, 12, 12, 12}, BandMargins{12, 0, 4, 8}, BandMargins{0, 20, 0, 0}}) {
    const Camera wide = widened_camera(c, m);
    EXPECT_EQ(wide.width_px, kWidth + m.left + m.right);
    EXPECT_EQ(wide.height_px, kHeight + m.top + m.bottom);
    for (const glm::vec3 p_world : {glm::vec3(0.0f, 2.0f, 0.0f), glm::vec3(1.7f, 1.0f, -0.6f), glm::vec3(-3.0f, 3.0f, 1.2f)}) {
      const glm::vec3 p_view = c.view_from_world_point(p_world);
      const glm::vec2 expected = c.pixel_from_view(p_view) + glm::vec2(float(m.left), float(m.top));
      const glm::vec2 got = wide.pixel_from_view(p_view);
      EXPECT_NEAR(got.x, expected.x, 1e-3f) << m.left << " " << m.top << " " << m.right << " " << m.bottom;
      EXPECT_NEAR(got.y, expected.y, 1e-3f) << m.left << " " << m.top << " " << m.right << " " << m.bottom;
      // And back: the widened camera's ray through the moved pixel meets the point.
      const glm::vec3 back = wide.view_from_pixel_depth(got, -p_view.z);
      EXPECT_NEAR(glm::distance(back, p_view), 0.0f, 1e-3f);
    }
  }
  EXPECT_EQ(widened_camera(c, 12).view_to_clip, widened_camera(c, BandMargins{12, 12, 12, 12}).view_to_clip);
}

TEST(GuardBand, WidthIsTheFarthestReachPastAnEdge) {
  // Facing a wall 6 units away: every pixel has the same projected radius r, and the edge
  // pixels (centres half a pixel in) reach r - 0.5 past the edge.
  raycast::Scene wall;
  wall.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  const GBuffer g = raycast::render_gbuffer(wall, camera_at(0.0f), 2);
  const float r_px = g.camera.pixels_per_unit(6.0f).x;  // radius 1
  ASSERT_GT(r_px, 10.0f);
  const auto ceil4 = [](float v) { return (int(std::ceil(v)) + 3) / 4 * 4; };
  EXPECT_EQ(guard_band_texels(g.depth_view, g.mask, g.camera, 1.0f, 256.0f, 2), ceil4(r_px - 0.5f));
  EXPECT_EQ(guard_band_texels(g.depth_view, g.mask, g.camera, 1.0f, 8.0f, 2), 8);  // max_radius_px bounds it
  EXPECT_EQ(guard_band_texels(g.depth_view, g.mask, g.camera, 100.0f, 256.0f, 2), 40);  // a quarter of 160
  EXPECT_EQ(guard_band_texels(g.depth_view, g.mask, g.camera, 1e-3f, 256.0f, 2), 0);  // no tap leaves
  EXPECT_EQ(guard_band_texels(g.depth_view, cv::Mat::zeros(g.mask.size(), CV_8UC1), g.camera, 1.0f, 256.0f, 2), 0);
}

// A wall with a box standing 0.3 units in front of it just past the left edge of the frame
// at x = 0 (seen by a camera moved left).
raycast::Scene box_off_screen_scene() {
  raycast::Scene s;
  s.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  s.boxes.push_back({{-3.9f, 2.4f, 0.0f}, {0.3f, 0.3f, 0.8f}, glm::mat3(1.0f), glm::vec3(0.8f)});
  return s;
}

TEST(GuardBand, ANeighbourFillsTheBandWithWhatItSaw) {
  const raycast::Scene scene = box_off_screen_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const std::vector<DepthView> views{view_of(scene, camera_at(-1.0f), "f-1")};
  std::vector<ViewUse> uses;
  const cv::Mat back = back_layer(g, views, &uses);
  ASSERT_TRUE(uses[0].used);
  const int margin = 24;
  GuardBand band;
  extend_with_views({g.depth_view, g.mask, g.camera}, back, views, uses, MultiViewSettings{}, margin, band, 2);
  // The view, a unit to the left, saw past the left edge as far as the band reaches.
  const BandMargins& m = band.margins;
  ASSERT_EQ(m.left, margin);
  ASSERT_EQ(band.depth_view.size(), cv::Size(kWidth + m.left + m.right, kHeight + m.top + m.bottom));
  // Inside: the frame's own depth and back layer, bit for bit.
  EXPECT_EQ(cv::norm(band.depth_view(band.inside()), g.depth_view, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(band.depth_back_view(band.inside()), back, cv::NORM_INF), 0.0);
  // The left band against a render of the widened camera: covered where the view saw, at
  // the depth the wider frame sees.
  const GBuffer exact = raycast::render_gbuffer(scene, band.camera, 2);
  int texels = 0, covered = 0, right = 0;
  for (int y = m.top; y < m.top + kHeight; ++y)
    for (int x = 0; x < m.left; ++x) {
      ++texels;
      const float d = band.depth_view.at<float>(y, x), e = exact.depth_view.at<float>(y, x);
      if (!std::isfinite(d)) continue;
      ++covered;
      right += std::abs(d - e) <= 0.01f * e;
      EXPECT_EQ(band.mask.at<uint8_t>(y, x), 255);
      EXPECT_GT(band.depth_back_view.at<float>(y, x), d);
    }
  std::printf("left band: %d of %d texels covered, %d within 1%% of the exact depth\n", covered, texels, right);
  EXPECT_GT(covered, texels * 8 / 10);
  EXPECT_GT(right, covered * 95 / 100);
}

TEST(GuardBand, IsNoWiderThanWhatTheViewsSaw) {
  const raycast::Scene scene = box_off_screen_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  // A view from the same pose sees nothing past the edges: no band.
  const std::vector<DepthView> same{view_of(scene, g.camera, "same")};
  std::vector<ViewUse> uses;
  const cv::Mat back = back_layer(g, same, &uses);
  ASSERT_TRUE(uses[0].used);
  GuardBand band;
  extend_with_views({g.depth_view, g.mask, g.camera}, back, same, uses, MultiViewSettings{}, 24, band, 2);
  EXPECT_FALSE(band.margins.any());
  EXPECT_EQ(band.camera.width_px, kWidth);
  // A view 0.05 to the left sees a few pixels past the left edge only.
  const std::vector<DepthView> near{view_of(scene, camera_at(-0.05f), "near")};
  const cv::Mat near_back = back_layer(g, near, &uses);
  extend_with_views({g.depth_view, g.mask, g.camera}, near_back, near, uses, MultiViewSettings{}, 24, band, 2);
  EXPECT_GT(band.margins.left, 0);
  EXPECT_LT(band.margins.left, 24);
  EXPECT_EQ(band.margins.left % 4, 0);
  // Nothing past the right edge, and little or nothing above and below.
  EXPECT_EQ(band.margins.right, 0);
  EXPECT_LE(band.margins.top + band.margins.bottom, band.margins.left);
  EXPECT_EQ(band.camera.width_px, kWidth + band.margins.left);
}

double left_strip_error(const cv::Mat& ao, const cv::Mat& reference, const cv::Mat& mask, int width_px) {
  const cv::Rect strip(0, 0, width_px, ao.rows);
  return compare_images(ao(strip), reference(strip), mask(strip)).mae;
}

TEST(GuardBand, AnOccluderJustOffScreenDarkensTheEdge) {
  const raycast::Scene scene = box_off_screen_scene();
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const cv::Mat reference = raycast::reference_ao(scene, g, 1.0f, 256, 7, 2);
  const int strip = int(g.camera.pixels_per_unit(5.4f).x);  // a radius at the box's depth
  const std::vector<DepthView> views{view_of(scene, camera_at(-0.5f), "f-1"), view_of(scene, camera_at(0.5f), "f+1")};
  for (const auto& [method, preset] : {std::pair{AoMethod::gtao, Preset::high}, std::pair{AoMethod::raymarch, Preset::low}}) {
    AoSettings s = ao_preset(method, preset);
    const TermInputs alone_in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
    const TermInputs views_in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera,
                              nullptr,      nullptr,       nullptr,         nullptr, views};
    TermOutputs alone, with;
    compute_terms(alone_in, {&s, nullptr, nullptr}, alone, {}, 2);
    compute_terms(views_in, {&s, nullptr, nullptr}, with, {}, 2);
    const double e0 = left_strip_error(alone.ao.ao, reference, g.mask, strip);
    const double e1 = left_strip_error(with.ao.ao, reference, g.mask, strip);
    std::printf("%s %s, the %d px by the left edge: MAE alone %.4f, with the guard band %.4f\n",
                std::string(to_string(method)).c_str(), std::string(to_string(preset)).c_str(), strip, e0, e1);
    EXPECT_LT(e1, 0.7 * e0);
  }
}

// SSDO's senders in the band reflect the light of the view that saw them. A white wall
// lit by a uniform sky, and a red box just past the left edge, 0.3 in front of it: by the
// edge the wall gets the box's red bounce. With the view's depth only, the band's box
// occludes but sends nothing; with its albedo and lighting it sends what the frame would
// have seen.
TEST(GuardBand, SendersInTheBandReflectTheLightOfTheViewThatSawThem) {
  raycast::Scene scene;
  scene.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  scene.boxes.push_back({{-3.9f, 2.4f, 0.0f}, {0.3f, 0.3f, 0.8f}, glm::mat3(1.0f), glm::vec3(0.9f, 0.1f, 0.1f)});
  const raycast::EnvironmentRadiance sky = raycast::uniform_environment();
  const Environment environment = Environment::constant(glm::vec3(1.0f));
  GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  g.lighting = raycast::reference_light(scene, g, sky, kInf, 64, 3, 2).direct;
  const SsdoSettings s = ssdo_preset(SsdoMethod::ssdo, Preset::high);
  const cv::Mat reference = raycast::reference_light(scene, g, sky, s.radius_world, 512, 5, 2).indirect;
  const GBuffer seen = raycast::render_gbuffer(scene, camera_at(-0.5f), 2);
  DepthView lit{seen.camera, seen.depth_view, "f-1"};
  lit.albedo = seen.albedo;
  lit.lighting = raycast::reference_light(scene, seen, sky, kInf, 64, 3, 2).direct;
  const DepthView depth_only{seen.camera, seen.depth_view, "f-1"};
  const cv::Rect edge(0, 0, int(g.camera.pixels_per_unit(5.4f).x), g.depth_view.rows);  // a radius at the box
  const auto red = [&](const cv::Mat& rgb) {
    cv::Mat r;
    cv::extractChannel(rgb(edge), r, 0);
    return r;
  };
  // The red indirect light by the edge with one view: its mean, and its MAE against the exact.
  const auto red_by_the_edge = [&](const DepthView& view, double& error) {
    const std::vector<DepthView> views{view};
    const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &environment,
                        &g.albedo,    &g.lighting,   nullptr,         views};
    TermOutputs out;
    compute_terms(in, {nullptr, &s, nullptr}, out, {}, 2);
    error = compare_images(red(out.ssdo.indirect), red(reference), g.mask(edge)).mae;
    return cv::mean(red(out.ssdo.indirect), g.mask(edge))[0];
  };
  double error_depth_only = 0, error_lit = 0;
  const double red_depth_only = red_by_the_edge(depth_only, error_depth_only);
  const double red_lit = red_by_the_edge(lit, error_lit);
  std::printf("red bounce by the left edge: exact %.4f; depth-only view %.4f (MAE %.4f), lit view %.4f (MAE %.4f)\n",
              cv::mean(red(reference), g.mask(edge))[0], red_depth_only, error_depth_only, red_lit, error_lit);
  EXPECT_GT(red_lit, red_depth_only + 0.01);
  EXPECT_LT(error_lit, error_depth_only);
}

// Kernel inputs of a grid padded by an empty band (no view saw anything past the edges).
struct PaddedGrid {
  cv::Mat depth_view, normal_view, position_view, mask;
  Camera camera;
};

PaddedGrid pad_empty(const GBuffer& g, int margin) {
  PaddedGrid p;
  const auto pad = [margin](const cv::Mat& src, cv::Mat& dst, cv::Scalar value) {
    cv::copyMakeBorder(src, dst, margin, margin, margin, margin, cv::BORDER_CONSTANT, value);
  };
  pad(g.depth_view, p.depth_view, cv::Scalar(kInf));
  pad(g.normal_view, p.normal_view, cv::Scalar::all(0));
  pad(g.position_view, p.position_view, cv::Scalar::all(0));
  pad(g.mask, p.mask, cv::Scalar(0));
  p.camera = widened_camera(g.camera, margin);
  return p;
}

// The band changes only the pixels whose taps reach it: elsewhere the same taps with the
// same noise, to the rounding of the widened projection (a tap a rounding away from a pixel
// edge may land in the other pixel: 6e-6 at most here, against 0.08-0.3 had the noise moved
// with the grid).
TEST(GuardBand, PixelsWhoseTapsStayOnScreenKeepTheirValues) {
  // A box against a wall: the wall round it is occluded.
  raycast::Scene scene;
  scene.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  scene.boxes.push_back({{0.0f, 2.6f, 0.0f}, {0.4f, 0.4f, 0.4f}, glm::mat3(1.0f), glm::vec3(0.8f)});
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const int margin = 16;
  const PaddedGrid p = pad_empty(g, margin);
  // Farther from every edge than any pixel's projected radius (the nearest surface is the
  // box's front, 5.2 units away): no tap of these pixels leaves the picture.
  double nearest = 0;
  cv::minMaxLoc(g.depth_view, &nearest, nullptr, nullptr, nullptr, g.mask);
  const int reach = int(std::ceil(g.camera.pixels_per_unit(float(nearest)).x)) + 1;
  const cv::Rect interior(reach, reach, kWidth - 2 * reach, kHeight - 2 * reach);
  ASSERT_GT(interior.area(), 0);
  for (const AoMethod method : {AoMethod::gtao, AoMethod::hbao, AoMethod::raymarch}) {
    AoSettings s = ao_preset(method, method == AoMethod::raymarch ? Preset::low : Preset::medium);
    // The constant thickness: a thickness estimated here would see the empty band as
    // background and the picture's border as a silhouette. (With views the band comes with
    // the views' back layer, estimated on the grid before it is extended: compute_terms.)
    s.thickness_model = ThicknessModel::constant;
    AoOutput alone, padded;
    compute_ao({g.depth_view, g.normal_view, g.position_view, g.mask, g.camera}, s, alone, {}, 2);
    compute_ao({p.depth_view, p.normal_view, p.position_view, p.mask, p.camera, nullptr, nullptr, {margin, margin}}, s,
               padded, cv::Rect(margin, margin, kWidth, kHeight), 2);
    const cv::Mat inside = padded.ao(cv::Rect(margin, margin, kWidth, kHeight));
    ASSERT_LT(cv::mean(alone.ao(interior))[0], 0.95) << "some occlusion to compare";
    EXPECT_LT(cv::norm(inside(interior), alone.ao(interior), cv::NORM_INF), 1e-4) << to_string(method);
  }
}

}  // namespace
}  // namespace ssdo::multiview_test
