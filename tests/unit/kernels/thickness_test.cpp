// Thickness from silhouettes (kernels/thickness.h) on frames whose silhouettes and
// distances are known exactly: a plate floating over the background, a plate in front of a
// wall, a wall alone.
#include "kernels/thickness.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace ssdo::thickness_test {
namespace {

constexpr int kSize = 101;
constexpr float kInf = std::numeric_limits<float>::infinity();

struct Frame {
  cv::Mat depth = cv::Mat(kSize, kSize, CV_32FC1, cv::Scalar(kInf));
  cv::Mat mask = cv::Mat::zeros(kSize, kSize, CV_8UC1);
  Camera camera = Camera::from_fov_x(kSize, kSize, 60.0f);

  void fill(const cv::Rect& r, float depth_view) {
    depth(r).setTo(depth_view);
    mask(r).setTo(255);
  }
};

// Scene units per pixel at this depth, as the kernel takes it.
float units_per_px(const Camera& c, float depth_view) { return 1.0f / c.pixels_per_unit(depth_view).y; }

// A plate of 41 x 41 pixels (columns and rows 30 .. 70) at depth 5 over background: its
// border pixels are its silhouette, and each pixel's thickness is 4 x (its distance to the
// border + 1/2 pixel) in scene units.
TEST(Thickness, PlateOverBackgroundIsAsDeepAsItIsWide) {
  Frame f;
  f.fill(cv::Rect(30, 30, 41, 41), 5.0f);
  cv::Mat back;
  const SilhouetteThicknessSettings s;
  estimate_back_depth(f.depth, f.mask, f.camera, s, back, 1);
  ASSERT_EQ(back.type(), CV_32FC1);
  const float u = units_per_px(f.camera, 5.0f);
  // The border: half a pixel.
  EXPECT_NEAR(back.at<float>(30, 50), 5.0f + 4.0f * 0.5f * u, 1e-5f);
  EXPECT_NEAR(back.at<float>(50, 70), 5.0f + 4.0f * 0.5f * u, 1e-5f);
  // The centre: 20 pixels from the border (the nearest silhouette cell's representative lies
  // on the same row or column here, so the distance is exact).
  EXPECT_NEAR(back.at<float>(50, 50), 5.0f + 4.0f * 20.5f * u, 1e-4f);
  // 5 pixels in from the left border, in the middle row.
  EXPECT_NEAR(back.at<float>(50, 35), 5.0f + 4.0f * 5.5f * u, 1e-4f);
  // Background: solid (never read).
  EXPECT_EQ(back.at<float>(0, 0), kInf);
  // Twice the factor, twice the thickness.
  SilhouetteThicknessSettings twice = s;
  twice.thickness_per_distance = 8.0f;
  cv::Mat back2;
  estimate_back_depth(f.depth, f.mask, f.camera, twice, back2, 1);
  EXPECT_NEAR(back2.at<float>(50, 50) - 5.0f, 2.0f * (back.at<float>(50, 50) - 5.0f), 1e-4f);
}

// The same plate 1 unit in front of a wall at depth 6: the plate is bounded by its
// silhouette as before; the wall's pixels, whose nearest silhouette is the plate's rim in
// front of them, and which nothing bounds, stay solid.
TEST(Thickness, WallBehindAPlateStaysSolid) {
  Frame f;
  f.fill(cv::Rect(0, 0, kSize, kSize), 6.0f);
  f.fill(cv::Rect(30, 30, 41, 41), 5.0f);
  cv::Mat back;
  estimate_back_depth(f.depth, f.mask, f.camera, {}, back, 0);
  const float u = units_per_px(f.camera, 5.0f);
  EXPECT_NEAR(back.at<float>(50, 50), 5.0f + 4.0f * 20.5f * u, 1e-4f);
  EXPECT_NEAR(back.at<float>(30, 40), 5.0f + 4.0f * 0.5f * u, 1e-5f);
  EXPECT_EQ(back.at<float>(29, 40), kInf);  // the wall just outside the rim
  EXPECT_EQ(back.at<float>(0, 0), kInf);
  // A step of less than edge_depth_ratio of the depth is no silhouette: the same frame with
  // the plate 0.5 units (< 10% of 5) in front of the wall is one surface, solid everywhere.
  Frame g;
  g.fill(cv::Rect(0, 0, kSize, kSize), 5.45f);
  g.fill(cv::Rect(30, 30, 41, 41), 5.0f);
  estimate_back_depth(g.depth, g.mask, g.camera, {}, back, 0);
  EXPECT_EQ(cv::countNonZero(back != kInf), 0);
}

// A frame that no silhouette crosses (a wall filling the picture; its border is the frame's,
// not a silhouette) is solid everywhere, and the result does not depend on the thread count.
TEST(Thickness, NoSilhouetteIsSolidAndThreadsDoNotMatter) {
  Frame f;
  f.fill(cv::Rect(0, 0, kSize, kSize), 3.0f);
  cv::Mat back;
  estimate_back_depth(f.depth, f.mask, f.camera, {}, back, 0);
  EXPECT_EQ(cv::countNonZero(back != kInf), 0);

  Frame p;
  p.fill(cv::Rect(10, 20, 60, 30), 4.0f);
  p.fill(cv::Rect(50, 40, 30, 50), 2.0f);
  cv::Mat one, two;
  estimate_back_depth(p.depth, p.mask, p.camera, {}, one, 1);
  estimate_back_depth(p.depth, p.mask, p.camera, {}, two, 4);
  EXPECT_EQ(cv::norm(one != two, cv::NORM_L1), 0.0);
}

// An image wider than 2^15 pixels, whose squared distances pass 2^31: a strip of 3 rows in
// front of background at its two left columns. Its silhouette is column 2; the far end, 49997
// pixels from it, is as thick as the distance says (to the representative of its nearest
// cell, pixel (2, 0)).
TEST(Thickness, AWideImageKeepsItsLongDistances) {
  constexpr int kWide = 50000;
  cv::Mat depth(3, kWide, CV_32FC1, cv::Scalar(5.0f)), mask(3, kWide, CV_8UC1, cv::Scalar(255));
  depth.colRange(0, 2).setTo(kInf);
  mask.colRange(0, 2).setTo(0);
  const Camera camera = Camera::from_fov_x(kWide, 3, 60.0f);
  cv::Mat back;
  estimate_back_depth(depth, mask, camera, {}, back, 2);
  const double distance = std::sqrt(double(kWide - 1 - 2) * double(kWide - 1 - 2) + 1.0);
  const double expected = 5.0 + 4.0 * (distance + 0.5) * double(units_per_px(camera, 5.0f));
  EXPECT_NEAR(back.at<float>(1, kWide - 1), expected, 1e-5 * expected);
  EXPECT_NEAR(back.at<float>(0, 2), 5.0 + 4.0 * 0.5 * double(units_per_px(camera, 5.0f)), 1e-5);
}

// A disc, whose silhouette pixels lie at every angle: each pixel's distance (read back from
// its thickness) is at least the exact Euclidean distance to the nearest silhouette pixel
// (brute force here) and at most 2 sqrt(2) pixels more (the transform runs over cells of
// 2 x 2 pixels); silhouette pixels are at distance 0.
TEST(Thickness, DistancesOverCellsStayWithinTheirBound) {
  Frame f;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x)
      if (std::hypot(x - 47.3, y - 52.6) < 37.0) f.fill(cv::Rect(x, y, 1, 1), 5.0f);
  std::vector<cv::Point> silhouette;
  for (int y = 1; y + 1 < kSize; ++y)
    for (int x = 1; x + 1 < kSize; ++x)
      if (f.mask.at<uint8_t>(y, x) && (!f.mask.at<uint8_t>(y, x - 1) || !f.mask.at<uint8_t>(y, x + 1) ||
                                       !f.mask.at<uint8_t>(y - 1, x) || !f.mask.at<uint8_t>(y + 1, x)))
        silhouette.push_back({x, y});
  cv::Mat back;
  estimate_back_depth(f.depth, f.mask, f.camera, {}, back, 2);
  const float u = units_per_px(f.camera, 5.0f);
  int checked = 0;
  double worst = 0, sum = 0;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      if (!f.mask.at<uint8_t>(y, x)) continue;
      double exact = 1e9;
      for (const cv::Point& p : silhouette) exact = std::min(exact, std::hypot(double(x - p.x), double(y - p.y)));
      const double estimated = (back.at<float>(y, x) - 5.0) / (4.0 * u) - 0.5;
      ASSERT_GE(estimated, exact - 1e-3) << x << ", " << y;
      ASSERT_LE(estimated, exact + 2.0 * std::sqrt(2.0) + 1e-3) << x << ", " << y;
      if (exact == 0.0) {
        EXPECT_NEAR(estimated, 0.0, 1e-3) << x << ", " << y;
      }
      worst = std::max(worst, estimated - exact);
      sum += estimated - exact;
      ++checked;
    }
  EXPECT_GT(checked, 4000);
  std::printf("distance over cells - exact: mean %.3f px, worst %.3f px\n", sum / checked, worst);
  EXPECT_GT(worst, 0.5);  // the cells do show
  EXPECT_LT(sum / checked, 0.5);
}

// A lone masked pixel inside the plate is a dropped sample, not a hole: its neighbours keep
// the plate's thickness there; two masked pixels side by side are a hole, rimmed by a
// silhouette.
TEST(Thickness, ALoneMaskedPixelMakesNoSilhouette) {
  Frame f;
  f.fill(cv::Rect(30, 30, 41, 41), 5.0f);
  f.depth.at<float>(50, 50) = kInf;
  f.mask.at<uint8_t>(50, 50) = 0;
  f.depth(cv::Rect(34, 66, 2, 1)).setTo(kInf);
  f.mask(cv::Rect(34, 66, 2, 1)).setTo(0);
  cv::Mat back;
  estimate_back_depth(f.depth, f.mask, f.camera, {}, back, 1);
  const float u = units_per_px(f.camera, 5.0f);
  // 19 px from the plate's right border (to within the cells' 2 sqrt(2) px), not 0.
  EXPECT_GE(back.at<float>(50, 51), 5.0f + 4.0f * 19.5f * u - 1e-4f);
  EXPECT_LE(back.at<float>(50, 51), 5.0f + 4.0f * (19.5f + 2.83f) * u);
  EXPECT_EQ(back.at<float>(50, 50), kInf);                              // the masked pixel itself
  EXPECT_NEAR(back.at<float>(66, 36), 5.0f + 4.0f * 0.5f * u, 1e-5f);   // beside the hole
}

TEST(Thickness, SettingsAreChecked) {
  EXPECT_EQ(validate(SilhouetteThicknessSettings{}), "");
  EXPECT_NE(validate(SilhouetteThicknessSettings{.edge_depth_ratio = 0.0f}).find("edge_depth_ratio"),
            std::string::npos);
  EXPECT_NE(validate(SilhouetteThicknessSettings{.thickness_per_distance = -1.0f}).find("thickness_per_distance"),
            std::string::npos);
  EXPECT_NE(validate(SilhouetteThicknessSettings{.thickness_per_distance = kInf}).find("thickness_per_distance"),
            std::string::npos);
}

}  // namespace
}  // namespace ssdo::thickness_test
