// view_positions_from_depth against Camera::view_from_pixel_depth, pixel by pixel: the
// vector solve gives the scalar solve's bits for every kind of projection, on rows whose
// width is no multiple of any vector's, inside a region and outside it.
#include "kernels/positions.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

namespace ssdo::positions_test {  // its own names in a unity batch of test files
namespace {

constexpr int kWidth = 157, kHeight = 23;  // odd: every row ends in a partial vector

Camera perspective() { return Camera::from_fov_x(kWidth, kHeight, 63.0f); }

// Off-axis (lens shift) with pixels 1.3 times as wide as tall: every term of the solve
// is used.
Camera shifted() {
  Camera c = Camera::from_fov_x(kWidth, kHeight, 40.0f, 0.1f, 500.0f, 1.3f);
  c.view_to_clip[2][0] = 0.17f;
  c.view_to_clip[2][1] = -0.09f;
  return c;
}

Camera orthographic() {
  Camera c;
  c.width_px = kWidth;
  c.height_px = kHeight;
  c.view_to_clip = glm::mat4(1.0f);
  c.view_to_clip[0][0] = 2.0f / 7.5f;
  c.view_to_clip[1][1] = 2.0f / 1.1f;
  c.view_to_clip[2][2] = -0.01f;
  c.view_to_clip[3][0] = 0.3f;
  c.view_to_clip[3][1] = -0.2f;
  return c;
}

struct DepthFrame {
  cv::Mat depth = cv::Mat(kHeight, kWidth, CV_32FC1);
  cv::Mat mask = cv::Mat(kHeight, kWidth, CV_8UC1);
};

// Depths over six decades (Cycles' background depth among them) under a mask with a fifth
// of the pixels off; masked pixels hold depths too (infinite or not), which must not leak.
DepthFrame random_frame(uint32_t seed) {
  DepthFrame f;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> decade(-1.0f, 4.0f), u(0.0f, 1.0f);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const float r = u(rng);
      f.depth.at<float>(y, x) = r < 0.05f ? std::numeric_limits<float>::infinity()
                                : r < 0.1f ? 1e10f
                                           : std::pow(10.0f, decade(rng));
      f.mask.at<uint8_t>(y, x) = u(rng) < 0.2f ? 0 : 255;
    }
  return f;
}

// 0 when every pixel inside `roi` holds the scalar solve's bits (0 where masked; a NaN as
// any NaN) and every pixel outside holds `outside`'s; else the number of pixels that do not.
int mismatches(const DepthFrame& f, const Camera& camera, const cv::Mat& positions, const cv::Rect& roi,
               const cv::Vec3f& outside) {
  int bad = 0;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      cv::Vec3f expected = outside;
      if (roi.contains({x, y})) {
        const glm::vec3 p = f.mask.at<uint8_t>(y, x)
                                ? camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, f.depth.at<float>(y, x))
                                : glm::vec3(0.0f);
        expected = cv::Vec3f(p.x, p.y, p.z);
      }
      const cv::Vec3f& got = positions.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) {
        // A NaN (an infinite depth's 0 x inf) is a NaN: its sign and payload follow the order in
        // which the compiler put the operands of each instruction, which scalar and vector code
        // need not share (AArch64 propagates the first operand's NaN).
        const bool both_nan = std::isnan(expected[c]) && std::isnan(got[c]);
        if (!both_nan && std::memcmp(&expected[c], &got[c], sizeof(float)) != 0) {
          ++bad;
          break;
        }
      }
    }
  return bad;
}

TEST(Positions, EveryPixelHasTheBitsOfTheCamerasSolve) {
  const DepthFrame f = random_frame(7);
  for (const Camera& camera : {perspective(), shifted(), orthographic()}) {
    cv::Mat positions;
    view_positions_from_depth(f.depth, f.mask, camera, positions, {}, 2);
    ASSERT_EQ(positions.type(), CV_32FC3);
    EXPECT_EQ(mismatches(f, camera, positions, cv::Rect(0, 0, kWidth, kHeight), {}), 0)
        << "projection [2][3] = " << camera.view_to_clip[2][3];
    // Not trivially zero: the foreground's points are at their depths.
    const cv::Vec3f p = positions.at<cv::Vec3f>(kHeight / 2, kWidth / 2);
    if (f.mask.at<uint8_t>(kHeight / 2, kWidth / 2)) {
      EXPECT_EQ(p[2], -f.depth.at<float>(kHeight / 2, kWidth / 2));
    }
  }
}

TEST(Positions, ARegionIsWrittenAloneWithTheSameBits) {
  const DepthFrame f = random_frame(11);
  const cv::Vec3f sentinel(-7.0f, -7.0f, -7.0f);
  for (const cv::Rect roi : {cv::Rect(3, 2, 131, 17), cv::Rect(150, 0, 7, kHeight), cv::Rect(0, 5, 1, 1)}) {
    cv::Mat positions(kHeight, kWidth, CV_32FC3, cv::Scalar(sentinel[0], sentinel[1], sentinel[2]));
    view_positions_from_depth(f.depth, f.mask, shifted(), positions, roi, 1);
    EXPECT_EQ(mismatches(f, shifted(), positions, roi, sentinel), 0) << roi;
  }
}

}  // namespace
}  // namespace ssdo::positions_test
