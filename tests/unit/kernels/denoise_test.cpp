#include "kernels/denoise.h"

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/raycast.h"

namespace ssdo {
namespace {

struct Guides {
  cv::Mat depth, normal, mask;
};

// Random smooth-ish guides with a few masked pixels and depth/normal jumps.
Guides random_guides(cv::Size size, uint64_t seed) {
  cv::RNG rng(seed);
  Guides g;
  g.depth.create(size, CV_32FC1);
  g.normal.create(size, CV_32FC3);
  g.mask.create(size, CV_8UC1);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      const bool far_side = x > size.width / 2;
      g.depth.at<float>(y, x) = (far_side ? 5.0f : 2.0f) + rng.uniform(0.0f, 0.1f);
      cv::Vec3f n(rng.uniform(-0.4f, 0.4f), rng.uniform(-0.4f, 0.4f), 1.0f);
      g.normal.at<cv::Vec3f>(y, x) = n / cv::norm(n);
      g.mask.at<uint8_t>(y, x) = rng.uniform(0, 20) == 0 ? 0 : 255;
    }
  return g;
}

// Brute force, obviously correct: the two passes written out with double sums, a tap every
// tap_spacing_px pixels within the radius.
cv::Mat brute_force(const cv::Mat& src, const Guides& g, const DenoiseSettings& s) {
  const int C = src.channels(), W = src.cols, H = src.rows, R = s.radius_px, D = s.tap_spacing_px;
  auto weight = [&](int cx, int cy, int tx, int ty, int k) -> double {
    if (tx < 0 || ty < 0 || tx >= W || ty >= H || !g.mask.at<uint8_t>(ty, tx)) return 0.0;
    if (k == 0) return 1.0;  // the centre: g(0), its depth weight and its unit normal's lobe are 1
    const double d = g.depth.at<float>(cy, cx), dt = g.depth.at<float>(ty, tx);
    const double wd = std::max(0.0, 1.0 - std::abs(dt - d) * (1.0 / d + 1.0 / dt) / (2.0 * s.depth_tolerance_relative));
    const double c = g.normal.at<cv::Vec3f>(cy, cx).dot(g.normal.at<cv::Vec3f>(ty, tx));
    const double wn = c > 0 ? std::pow(c, double(s.normal_power)) : 0.0;
    return std::exp(-0.5 * k * k / (double(s.sigma_px) * s.sigma_px)) * wd * wn;
  };
  cv::Mat tmp = src.clone(), out = src.clone();
  for (int pass = 0; pass < 2; ++pass) {
    const cv::Mat& in = pass == 0 ? src : tmp;
    cv::Mat& o = pass == 0 ? tmp : out;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        if (!g.mask.at<uint8_t>(y, x)) continue;
        std::vector<double> sum(C, 0.0);
        double wsum = 0.0;
        for (int k = -(R / D) * D; k <= R; k += D) {
          const int tx = pass == 0 ? x + k : x, ty = pass == 0 ? y : y + k;
          const double w = weight(x, y, tx, ty, k);
          if (w == 0.0) continue;
          for (int c = 0; c < C; ++c) sum[c] += w * in.ptr<float>(ty)[tx * C + c];
          wsum += w;
        }
        for (int c = 0; c < C; ++c) o.ptr<float>(y)[x * C + c] = float(sum[c] / wsum);
      }
  }
  return out;
}

// The filter of a random 1- and 3-channel image within 1e-5 of the brute force.
void expect_matches_brute_force(const Guides& g, const DenoiseSettings& s, int threads, const std::string& what) {
  for (int channels : {1, 3}) {
    cv::Mat src(g.depth.size(), CV_MAKETYPE(CV_32F, channels));
    cv::randu(src, 0.0f, 1.0f);
    cv::Mat dst;
    denoise_bilateral(src, g.depth, g.normal, g.mask, s, dst, {}, threads);
    EXPECT_LE(cv::norm(dst, brute_force(src, g, s), cv::NORM_INF), 1e-5) << what << ", " << channels << " channels";
  }
}

// The default power (compile-time lobe) and others (integer and fractional, the general
// lobe), one and three channels.
TEST(Denoise, MatchesBruteForce) {
  const Guides g = random_guides(cv::Size(37, 29), 7);
  for (const float power : {16.0f, 7.0f, 2.5f, 1.0f, 0.0f}) {
    DenoiseSettings s;
    s.normal_power = power;
    expect_matches_brute_force(g, s, 1, "power " + std::to_string(power));
  }
}

// Taps spaced apart (the half grid's footprint, and a radius that is no multiple of the
// spacing), against the brute force; wider and taller than a tile (256 x 64 pixels), so
// the seams are crossed both ways, and on one and two threads, whose first blocks of rows
// (200 and 96 rows) hold several tiles, each taking its halo rows from the tile above.
TEST(Denoise, SpacedTapsMatchBruteForce) {
  const Guides g = random_guides(cv::Size(300, 200), 13);
  for (const auto& [radius, spacing] : {std::pair{8, 2}, std::pair{7, 3}, std::pair{32, 4}})
    for (int threads : {1, 2}) {
      DenoiseSettings s;
      s.radius_px = radius;
      s.sigma_px = 2.5f * float(spacing);
      s.tap_spacing_px = spacing;
      expect_matches_brute_force(g, s, threads,
                                 "radius " + std::to_string(radius) + ", spacing " + std::to_string(spacing) + ", " +
                                     std::to_string(threads) + " threads");
    }
}

// Taller than two tiles, so that two threads take different strips of rows.
TEST(Denoise, OneAndTwoThreadsIdentical) {
  const cv::Size size(64, 200);
  const Guides g = random_guides(size, 3);
  cv::Mat src(size, CV_32FC3), a, b;
  cv::randu(src, 0.0f, 1.0f);
  denoise_bilateral(src, g.depth, g.normal, g.mask, {}, a, {}, 1);
  denoise_bilateral(src, g.depth, g.normal, g.mask, {}, b, {}, 2);
  EXPECT_EQ(0, std::memcmp(a.data, b.data, a.total() * a.elemSize()));
}

// Several images in one pass: each result is the same bits as denoising it alone, for
// channel counts up to one pass's (1 + 3 + 3 = 7, 3 + 3, 1 + 3, 1 + 1) and beyond it
// (3 + 3 + 3: two passes), with both lobes (the default power, integer and fractional).
TEST(Denoise, SeveralImagesInOnePassMatchEachAloneBitForBit) {
  const cv::Size size(300, 41);  // wider than a tile: the tile seams are crossed
  const Guides g = random_guides(size, 11);
  for (const float power : {16.0f, 8.0f, 2.5f}) {
    DenoiseSettings s;
    s.normal_power = power;
    for (const std::vector<int>& layout :
         std::vector<std::vector<int>>{{1, 3, 3}, {3, 3}, {1, 3}, {1, 1}, {3, 3, 3}}) {
      std::vector<cv::Mat> srcs, together(layout.size());
      std::vector<const cv::Mat*> src_ptrs;
      std::vector<cv::Mat*> dst_ptrs;
      for (size_t i = 0; i < layout.size(); ++i) {
        srcs.emplace_back(size, CV_MAKETYPE(CV_32F, layout[i]));
        cv::randu(srcs.back(), 0.0f, 1.0f);
      }
      for (size_t i = 0; i < layout.size(); ++i) {
        src_ptrs.push_back(&srcs[i]);
        dst_ptrs.push_back(&together[i]);
      }
      denoise_bilateral(src_ptrs, g.depth, g.normal, g.mask, s, dst_ptrs, {}, 2);
      for (size_t i = 0; i < layout.size(); ++i) {
        cv::Mat alone;
        denoise_bilateral(srcs[i], g.depth, g.normal, g.mask, s, alone, {}, 1);
        ASSERT_EQ(alone.type(), together[i].type());
        EXPECT_EQ(0, std::memcmp(alone.data, together[i].data, alone.total() * alone.elemSize()))
            << "power " << power << ", image " << i << " of " << layout.size();
      }
    }
  }
}

TEST(Denoise, StepEdgeDoesNotBleed) {
  // Left half at depth 2, right half at depth 5; the image is constant on each side, so
  // any weight across the edge would move a value.
  const cv::Size size(40, 30);
  cv::Mat depth(size, CV_32FC1), normal(size, CV_32FC3, cv::Scalar(0, 0, 1)),
      mask(size, CV_8UC1, cv::Scalar(255)), src(size, CV_32FC1);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      depth.at<float>(y, x) = x < 20 ? 2.0f : 5.0f;
      src.at<float>(y, x) = x < 20 ? 0.25f : 0.75f;
    }
  cv::Mat dst;
  DenoiseSettings s;
  s.radius_px = 8;
  denoise_bilateral(src, depth, normal, mask, s, dst);
  // A weighted mean of equal values rounds within a few ulps; one tap across the edge
  // would move a value by >= 0.5 * its relative weight (> 1e-3 here).
  EXPECT_LE(cv::norm(dst, src, cv::NORM_INF), 1e-6);
  // Noise on the left side stays on the left side.
  cv::Mat noisy = src.clone();
  cv::randu(noisy(cv::Rect(0, 0, 20, 30)), 0.0f, 0.5f);
  denoise_bilateral(noisy, depth, normal, mask, s, dst);
  EXPECT_LE(cv::norm(dst(cv::Rect(20, 0, 20, 30)), src(cv::Rect(20, 0, 20, 30)), cv::NORM_INF), 1e-6);
}

TEST(Denoise, MaskedPixelsUntouchedAndNotRead) {
  const cv::Size size(32, 24);
  const Guides g = random_guides(size, 11);
  cv::Mat src(size, CV_32FC1);
  cv::randu(src, 0.0f, 1.0f);
  cv::Mat a, b;
  denoise_bilateral(src, g.depth, g.normal, g.mask, {}, a);
  cv::Mat poisoned = src.clone();
  poisoned.setTo(1e6f, g.mask == 0);  // masked values must never be read
  denoise_bilateral(poisoned, g.depth, g.normal, g.mask, {}, b);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      if (g.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(a.at<float>(y, x), b.at<float>(y, x));
      } else {
        EXPECT_EQ(a.at<float>(y, x), src.at<float>(y, x));
      }
    }
}

TEST(Denoise, IsolatedPixelKeepsItsValue) {
  // Every neighbour masked or across an edge: the centre weight alone, no 0/0.
  const cv::Size size(5, 5);
  cv::Mat depth(size, CV_32FC1, cv::Scalar(9.0f)), normal(size, CV_32FC3, cv::Scalar(0, 0, 1)),
      mask(size, CV_8UC1, cv::Scalar(255)), src(size, CV_32FC1, cv::Scalar(0.0f));
  depth.at<float>(2, 2) = 1.0f;
  src.at<float>(2, 2) = 0.5f;
  cv::Mat dst;
  denoise_bilateral(src, depth, normal, mask, {}, dst);
  EXPECT_EQ(dst.at<float>(2, 2), 0.5f);
}

TEST(Denoise, RoiWritesOnlyInside) {
  const cv::Size size(40, 30);
  const Guides g = random_guides(size, 5);
  cv::Mat src(size, CV_32FC1), full, part(size, CV_32FC1, cv::Scalar(-3.0f));
  cv::randu(src, 0.0f, 1.0f);
  denoise_bilateral(src, g.depth, g.normal, g.mask, {}, full);
  const cv::Rect roi(7, 5, 20, 13);
  denoise_bilateral(src, g.depth, g.normal, g.mask, {}, part, roi, 2);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      if (roi.contains({x, y})) {
        EXPECT_EQ(part.at<float>(y, x), full.at<float>(y, x));
      } else {
        EXPECT_EQ(part.at<float>(y, x), -3.0f);
      }
    }
}

TEST(BoxBlur4x4, AveragesTheBlockAndRemovesATiledPattern) {
  cv::Mat src(16, 16, CV_32FC1), dst;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) src.at<float>(y, x) = float((x & 3) + 4 * (y & 3));  // 0..15 tile
  box_blur_4x4(src, dst);
  // Interior: any 4x4 block covers the tile once -> the tile mean 7.5.
  for (int y = 2; y < 15; ++y)
    for (int x = 2; x < 15; ++x) EXPECT_FLOAT_EQ(dst.at<float>(y, x), 7.5f);
  // Corner (0, 0): only offsets 0 and 1 are inside: mean of values 0, 1, 4, 5.
  EXPECT_FLOAT_EQ(dst.at<float>(0, 0), 2.5f);
}

// A half-grid term's footprint is twice the full grid's, the radius at most the bound.
TEST(DenoiseSettings, ScaledToTheGridOfTheTerm) {
  const DenoiseSettings s;
  const DenoiseSettings full = scaled_to_grid(s, 1), half = scaled_to_grid(s, 2);
  EXPECT_EQ(full.radius_px, s.radius_px);
  EXPECT_EQ(full.sigma_px, s.sigma_px);
  EXPECT_EQ(half.radius_px, 2 * s.radius_px);
  EXPECT_EQ(half.sigma_px, 2.0f * s.sigma_px);
  EXPECT_EQ(full.tap_spacing_px, 1);
  EXPECT_EQ(half.tap_spacing_px, 2);
  EXPECT_EQ(half.depth_tolerance_relative, s.depth_tolerance_relative);
  EXPECT_EQ(half.normal_power, s.normal_power);
  DenoiseSettings wide;
  wide.radius_px = 20;
  EXPECT_EQ(scaled_to_grid(wide, 2).radius_px, 32);
  EXPECT_TRUE(validate(scaled_to_grid(wide, 2)).empty());
}

TEST(DenoiseSettings, Validate) {
  EXPECT_TRUE(validate(DenoiseSettings{}).empty());
  DenoiseSettings s;
  s.radius_px = 33;
  EXPECT_FALSE(validate(s).empty());
  s = {};
  s.depth_tolerance_relative = 0.0f;
  EXPECT_FALSE(validate(s).empty());
  s = {};
  s.tap_spacing_px = 0;
  EXPECT_NE(validate(s).find("tap_spacing_px"), std::string::npos);
  s.tap_spacing_px = 5;
  EXPECT_NE(validate(s).find("tap_spacing_px"), std::string::npos);
}

// What the blur of a roi reads: the roi grown by the farthest tap (a multiple of the
// spacing), clipped to the image; and the blur of the roi over a source that holds only
// those pixels gives the bits of the blur over the whole source.
TEST(Denoise, ReadsTheRoiGrownByTheFarthestTap) {
  const cv::Size size(100, 60);
  DenoiseSettings s;
  s.radius_px = 5;
  s.tap_spacing_px = 2;  // taps at 0, 2, 4: reach 4
  EXPECT_EQ(denoise_reads(cv::Rect(10, 10, 20, 20), s, size), cv::Rect(6, 6, 28, 28));
  EXPECT_EQ(denoise_reads(cv::Rect(0, 50, 100, 10), s, size), cv::Rect(0, 46, 100, 14));
  s.tap_spacing_px = 1;
  EXPECT_EQ(denoise_reads(cv::Rect(10, 10, 20, 20), s, size), cv::Rect(5, 5, 30, 30));
  s.radius_px = 0;
  EXPECT_EQ(denoise_reads(cv::Rect(10, 10, 20, 20), s, size), cv::Rect(10, 10, 20, 20));

  const GBuffer g = raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(100, 60), 0);
  cv::Mat src(size, CV_32FC1);
  cv::randu(src, 0.0f, 1.0f);
  s = DenoiseSettings{};
  s.tap_spacing_px = 2;
  s.radius_px = 7;
  const cv::Rect roi(30, 20, 25, 15);
  cv::Mat whole, part;
  denoise_bilateral(src, g.depth_view, g.normal_view, g.mask, s, whole, {}, 2);
  cv::Mat only_read = cv::Mat::zeros(size, CV_32FC1);
  src(denoise_reads(roi, s, size)).copyTo(only_read(denoise_reads(roi, s, size)));
  denoise_bilateral(only_read, g.depth_view, g.normal_view, g.mask, s, part, roi, 2);
  EXPECT_EQ(cv::norm(part(roi), whole(roi), cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace ssdo
