// The pass after reading, a vector of pixels at a time, against itself one pixel at a time
// (a one-pixel row runs no vector group): the same bits on every instruction set this CPU
// runs, for every kind of pixel at every lane position.
#include "formats/foreground_pass.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/each_simd_target.h"

namespace ssdo::foreground {
namespace {

uint32_t bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

// One row's buffers.
struct Row {
  std::vector<float> depth;
  std::vector<uint8_t> mask, repair;
  std::vector<cv::Vec3f> normal;
  ForegroundRow at(int x) { return {&depth[x], &mask[x], &normal[x], &repair[x]}; }
};

// Mostly foreground pixels with unit-ish normals (the vector groups' case), one in ~12
// of another kind: each reason a pixel is background or its normal unusable.
Row random_row(int width, unsigned seed, const ForegroundPass& pass) {
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f), depth(0.5f, 80.0f);
  Row r{std::vector<float>(width), std::vector<uint8_t>(width, 7),
        std::vector<uint8_t>(width, 0), std::vector<cv::Vec3f>(width)};
  for (int x = 0; x < width; ++x) {
    r.depth[x] = depth(rng);
    r.normal[x] = cv::Vec3f(unit(rng), unit(rng), unit(rng));
    switch (rng() % 12 == 0 ? rng() % 12 : 99) {
      case 0: r.depth[x] = nan; break;
      case 1: r.depth[x] = inf; break;
      case 2: r.depth[x] = -1.0f; break;
      case 3: r.depth[x] = 1e10f; break;
      case 4: r.depth[x] = pass.background; break;
      case 5: r.depth[x] = pass.far_view * 1.5f; break;
      case 6: r.normal[x] = cv::Vec3f(0, 0, 0); break;
      case 7: r.normal[x][1] = nan; break;
      case 8: r.normal[x] = cv::Vec3f(1e-8f, 0, 0); break;
      case 9: r.depth[x] = 0.0f; break;
      case 10: r.depth[x] = 1e-23f; break;
      case 11: r.normal[x] *= 1e20f; break;
      default: break;
    }
  }
  return r;
}

void expect_same_rows(const ForegroundPass& pass, int width, unsigned seed) {
  const glm::vec3 ray_row = row_ray(pass, 7);
  Row whole = random_row(width, seed, pass), single = whole;
  const RowCounts counts = foreground_row(pass, ray_row, whole.at(0));
  ForegroundPass one = pass;
  one.width = 1;
  RowCounts sum;
  for (int x = 0; x < width; ++x) {
    const RowCounts c = foreground_row(one, eye_ray(pass, ray_row, x), single.at(x));
    sum.foreground += c.foreground, sum.nonfinite += c.nonfinite, sum.repaired += c.repaired;
    sum.depth_min = std::min(sum.depth_min, c.depth_min);
    sum.depth_max = std::max(sum.depth_max, c.depth_max);
  }
  for (int x = 0; x < width; ++x) {
    ASSERT_EQ(bits(whole.depth[x]), bits(single.depth[x])) << "pixel " << x;
    ASSERT_EQ(whole.mask[x], single.mask[x]) << "pixel " << x;
    ASSERT_EQ(whole.repair[x], single.repair[x]) << "pixel " << x;
    for (int k = 0; k < 3; ++k)
      ASSERT_EQ(bits(whole.normal[x][k]), bits(single.normal[x][k])) << "pixel " << x << "." << k;
  }
  EXPECT_GT(counts.foreground, width / 2);
  EXPECT_EQ(counts.foreground, sum.foreground);
  EXPECT_EQ(counts.nonfinite, sum.nonfinite);
  EXPECT_EQ(counts.repaired, sum.repaired);
  EXPECT_EQ(bits(counts.depth_min), bits(sum.depth_min));
  EXPECT_EQ(bits(counts.depth_max), bits(sum.depth_max));
}

TEST(ForegroundPass, VectorGroupsGiveEachPixelsBits) {
  ForegroundPass pass;
  pass.width = 1003;  // not a multiple of any vector width: a tail
  pass.ray_origin = glm::vec3(-0.71f, 0.4f, -1.0f);
  pass.ray_step_x = glm::vec3(0.0013f, 0.0f, 0.0f);
  pass.ray_step_y = glm::vec3(0.0f, -0.0013f, 0.0f);
  pass.normal_to_view = glm::mat3(glm::vec3(0.8f, 0.0f, -0.6f), glm::vec3(0.1f, 0.98f, 0.13f),
                                  glm::vec3(0.59f, -0.2f, 0.78f));
  for (bool perspective : {true, false})
    for (bool world : {true, false})
      for (bool radial : {true, false}) {
        pass.perspective = perspective, pass.normals_world = world, pass.radial = radial;
        pass.far_view = radial ? 60.0f : 0.0f;
        pass.has_background = !radial, pass.background = 33.0f;
        SCOPED_TRACE(::testing::Message() << "perspective " << perspective << ", world "
                                          << world << ", radial " << radial);
        test::for_each_simd_target([&](const std::string& target) {
          SCOPED_TRACE(target);
          expect_same_rows(pass, pass.width, unsigned(perspective * 4 + world * 2 + radial));
        });
      }
}

// A depth below kMinForegroundDepth is background (the kernels' 1 / d and products of depths
// overflow); a finite normal whose squared length overflows keeps its direction.
TEST(ForegroundPass, TinyDepthIsBackgroundAndHugeNormalsKeepTheirDirection) {
  ForegroundPass pass;
  pass.width = 3;
  pass.ray_origin = glm::vec3(0.0f, 0.0f, -1.0f);
  pass.ray_step_x = glm::vec3(0.01f, 0.0f, 0.0f);
  pass.perspective = true;
  Row r{{1e-23f, 2.0f, 2.0f}, std::vector<uint8_t>(3, 7), std::vector<uint8_t>(3, 0),
        {cv::Vec3f(0, 0, 1), cv::Vec3f(0, 3e20f, 4e20f), cv::Vec3f(3e38f, 3e38f, 0)}};
  const RowCounts counts = foreground_row(pass, row_ray(pass, 0), r.at(0));
  EXPECT_EQ(r.mask[0], 0);
  EXPECT_EQ(r.depth[0], std::numeric_limits<float>::infinity());
  EXPECT_EQ(r.mask[1], 255);
  EXPECT_EQ(r.repair[1], 0);
  EXPECT_NEAR(r.normal[1][1], 0.6f, 1e-6f);
  EXPECT_NEAR(r.normal[1][2], 0.8f, 1e-6f);
  EXPECT_EQ(r.mask[2], 255);  // its length overflows even scaled: (1, 1, 0) / sqrt 2
  EXPECT_NEAR(std::abs(r.normal[2][0]), std::sqrt(0.5f), 1e-6f);  // turned to face the eye
  EXPECT_EQ(counts.foreground, 2);
  EXPECT_EQ(counts.repaired, 0);
}

}  // namespace
}  // namespace ssdo::foreground
