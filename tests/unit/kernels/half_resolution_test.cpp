// The half grid and its upsample (kernels/half_resolution.h).
#include "kernels/half_resolution.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

#include <gtest/gtest.h>

#include "core/half_samples.h"
#include "tests/support/image_difference.h"

#include "kernels/ao.h"
#include "kernels/confidence.h"
#include "kernels/denoise.h"
#include "kernels/positions.h"
#include "tests/support/raycast.h"
#include "kernels/ssdo.h"

namespace ssdo {
namespace {

// The cornell scene of the ray caster at an odd size (the last half-grid column and row
// stand for one pixel only).
GBuffer frame() { return raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(161, 91), 0); }

// The test frame, its full grid and its half grid (2 threads).
struct FrameGrids {
  GBuffer g = frame();
  FullGrid full{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
  HalfGrid h;
  FrameGrids() { build_half_grid(full, h, 2); }
};

TEST(HalfResolution, GridTakesTheFirstForegroundPixelOfEachBlock) {
  const FrameGrids grids;
  const GBuffer& g = grids.g;
  const HalfGrid& h = grids.h;
  ASSERT_EQ(h.depth_view.size(), cv::Size(81, 46));
  EXPECT_EQ(h.camera.width_px, 81);
  EXPECT_EQ(h.camera.height_px, 46);
  int foreground = 0;
  for (int j = 0; j < h.depth_view.rows; ++j)
    for (int i = 0; i < h.depth_view.cols; ++i) {
      const cv::Vec2i src = h.source.at<cv::Vec2i>(j, i);
      if (src[0] < 0) {
        EXPECT_EQ(h.mask.at<uint8_t>(j, i), 0);
        EXPECT_TRUE(std::isinf(h.depth_view.at<float>(j, i)));
        continue;
      }
      ++foreground;
      // Inside its 2x2 block, and every block pixel before it (in the order (0,0), (1,0),
      // (0,1), (1,1)) is background.
      EXPECT_EQ(src[0] / 2, i);
      EXPECT_EQ(src[1] / 2, j);
      for (int k = 0; k < (src[0] & 1) + 2 * (src[1] & 1); ++k)
        EXPECT_EQ(g.mask.at<uint8_t>(2 * j + (k >> 1), 2 * i + (k & 1)), 0);
      EXPECT_EQ(h.depth_view.at<float>(j, i), g.depth_view.at<float>(src[1], src[0]));
      EXPECT_EQ(h.normal_view.at<cv::Vec3f>(j, i), g.normal_view.at<cv::Vec3f>(src[1], src[0]));
      EXPECT_EQ(h.position_view.at<cv::Vec3f>(j, i), g.position_view.at<cv::Vec3f>(src[1], src[0]));
    }
  EXPECT_GT(foreground, 81 * 46 / 2);
}

TEST(HalfResolution, UpsampleKeepsConstantsAndEachPixelsOwnSurface) {
  const FrameGrids grids;
  const GBuffer& g = grids.g;
  const FullGrid& full = grids.full;
  const HalfGrid& h = grids.h;
  // A value that is the texel's depth: upsampled, a pixel gets a mean of depths of its own
  // surface (within a few percent of its own depth), never one across a silhouette.
  cv::Mat half_value = h.depth_view.clone();
  half_value.setTo(0.0f, h.mask == 0);
  cv::Mat constant(h.depth_view.size(), CV_32FC3, cv::Scalar(0.25, 0.5, 0.75));
  cv::Mat full_value(g.depth_view.size(), CV_32FC1, cv::Scalar(-1.0));
  cv::Mat full_constant(g.depth_view.size(), CV_32FC3, cv::Scalar(-1, -1, -1));
  const UpsampleImage images[] = {{half_value, full_value, cv::Scalar(7.0), cv::Scalar(9.0)},
                                  {constant, full_constant, cv::Scalar(0, 0, 0), cv::Scalar(0, 0, 0)}};
  const cv::Rect roi(3, 5, 150, 80);
  upsample_from_half_grid(full, h, images, roi, 2);
  // A pixel whose surface no texel nearby took (thin features, the corners of silhouettes)
  // gets the nearby texel closest in depth: a value of another surface, so not all are near.
  int checked = 0, near_own_depth = 0;
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      const float v = full_value.at<float>(y, x);
      if (!roi.contains({x, y})) {
        EXPECT_EQ(v, -1.0f) << "outside the roi";
        continue;
      }
      if (!g.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(v, 7.0f);
        EXPECT_EQ(full_constant.at<cv::Vec3f>(y, x), cv::Vec3f(0, 0, 0));
        continue;
      }
      const float d = g.depth_view.at<float>(y, x);
      if (std::abs(v - d) <= 0.05f * d) ++near_own_depth;
      const cv::Vec3f c = full_constant.at<cv::Vec3f>(y, x);
      EXPECT_NEAR(c[0], 0.25f, 1e-6f);
      EXPECT_NEAR(c[1], 0.5f, 1e-6f);
      EXPECT_NEAR(c[2], 0.75f, 1e-6f);
      ++checked;
    }
  EXPECT_GT(checked, 5000);
  EXPECT_GT(near_own_depth, 0.98 * checked);
}

// One upsample of several images gives each image the bits of its upsample alone (the
// weights are shared, the blend is per image).
TEST(HalfResolution, UpsampleOfSeveralImagesGivesTheBitsOfEachAlone) {
  const FrameGrids grids;
  const GBuffer& g = grids.g;
  const FullGrid& full = grids.full;
  const HalfGrid& h = grids.h;
  cv::Mat gray(h.depth_view.size(), CV_32FC1), color(h.depth_view.size(), CV_32FC3);
  cv::randu(gray, 0.0f, 1.0f);
  cv::randu(color, 0.0f, 1.0f);
  cv::Mat gray_alone(g.depth_view.size(), CV_32FC1, cv::Scalar::all(-1)), gray_together = gray_alone.clone();
  cv::Mat color_alone(g.depth_view.size(), CV_32FC3, cv::Scalar::all(-1)), color_together = color_alone.clone();
  const cv::Rect roi(3, 5, 150, 80);
  upsample_from_half_grid(full, h, std::vector<UpsampleImage>{{gray, gray_alone, cv::Scalar(7), cv::Scalar(9)}}, roi, 2);
  upsample_from_half_grid(full, h, std::vector<UpsampleImage>{{color, color_alone, cv::Scalar::all(1), cv::Scalar::all(2)}},
                          roi, 1);
  const UpsampleImage together[] = {{gray, gray_together, cv::Scalar(7), cv::Scalar(9)},
                                    {color, color_together, cv::Scalar::all(1), cv::Scalar::all(2)}};
  upsample_from_half_grid(full, h, together, roi, 2);
  EXPECT_EQ(cv::norm(gray_alone, gray_together, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(color_alone, color_together, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::countNonZero(gray_together == -1), 161 * 91 - roi.area());
}

// A half-float image gets the float image's values, finished, rounded to half
// (half_samples::to_half), in the roi only; a float image beside it keeps its bits.
TEST(HalfResolution, UpsampleIntoHalfStoresTheFinishedFloatsInHalf) {
  const FrameGrids grids;
  const GBuffer& g = grids.g;
  cv::Mat vectors(grids.h.depth_view.size(), CV_32FC3), gray(grids.h.depth_view.size(), CV_32FC1);
  cv::randu(vectors, -1.0f, 1.0f);
  cv::randu(gray, 0.0f, 1.0f);
  cv::Mat as_float(g.depth_view.size(), CV_32FC3), gray_alone(g.depth_view.size(), CV_32FC1);
  cv::Mat as_half(g.depth_view.size(), CV_16FC3, cv::Scalar::all(7)), gray_beside(g.depth_view.size(), CV_32FC1);
  const cv::Rect roi(3, 5, 150, 80);
  const UpsampleImage floats[] = {{vectors, as_float, cv::Scalar::all(0), cv::Scalar::all(0), UpsampleFinish::unit_vector},
                                  {gray, gray_alone, cv::Scalar(1), cv::Scalar(1)}};
  const UpsampleImage mixed[] = {{vectors, as_half, cv::Scalar::all(0), cv::Scalar::all(0), UpsampleFinish::unit_vector},
                                 {gray, gray_beside, cv::Scalar(1), cv::Scalar(1)}};
  upsample_from_half_grid(grids.full, grids.h, floats, roi, 2);
  upsample_from_half_grid(grids.full, grids.h, mixed, roi, 2);
  EXPECT_EQ(cv::norm(gray_alone(roi), gray_beside(roi), cv::NORM_INF), 0.0);
  cv::Mat want(roi.size(), CV_16FC3);
  for (int y = 0; y < roi.height; ++y)
    half_samples::to_half(as_float.ptr<float>(roi.y + y) + 3 * roi.x, 3 * roi.width, want.ptr<uint16_t>(y));
  auto bits = [](const cv::Mat& m) { return cv::Mat(m.rows, m.cols, CV_16UC3, m.data, m.step); };
  EXPECT_EQ(cv::norm(bits(as_half(roi)), bits(want), cv::NORM_INF), 0.0);
  // Outside the roi nothing is written.
  cv::Mat outside = as_half.clone();
  outside(roi).setTo(cv::Scalar::all(7));
  cv::Mat outside_values;
  outside.convertTo(outside_values, CV_32F);
  EXPECT_EQ(cv::countNonZero(outside_values.reshape(1) != 7.0f), 0);
}

// The finishes: the clamp to [0, 1] of each value, and each foreground vector over its
// length (the pixel's normal at zero length), on the upsampled values; background keeps
// its value and pixels outside the roi are not written.
TEST(HalfResolution, UpsampleFinishesClampAndRenormaliseTheBlendedValues) {
  const FrameGrids grids;
  const GBuffer& g = grids.g;
  const FullGrid& full = grids.full;
  const HalfGrid& h = grids.h;
  cv::Mat gray(h.depth_view.size(), CV_32FC1), vector(h.depth_view.size(), CV_32FC3);
  cv::randu(gray, -0.5f, 1.5f);
  cv::randu(vector, -1.0f, 1.0f);
  vector(cv::Rect(10, 10, 6, 6)).setTo(cv::Scalar::all(0));  // zero length: the normal
  const cv::Rect roi(3, 5, 150, 80);
  cv::Mat gray_plain(g.depth_view.size(), CV_32FC1, cv::Scalar::all(-3)), gray_finished = gray_plain.clone();
  cv::Mat vector_plain(g.depth_view.size(), CV_32FC3, cv::Scalar::all(-3)), vector_finished = vector_plain.clone();
  const UpsampleImage plain[] = {{gray, gray_plain, cv::Scalar(7), cv::Scalar(9)},
                                 {vector, vector_plain, cv::Scalar::all(0), cv::Scalar::all(0)}};
  const UpsampleImage finished[] = {
      {gray, gray_finished, cv::Scalar(7), cv::Scalar(9), UpsampleFinish::clamp_unit_interval},
      {vector, vector_finished, cv::Scalar::all(0), cv::Scalar::all(0), UpsampleFinish::unit_vector}};
  upsample_from_half_grid(full, h, plain, roi, 2);
  upsample_from_half_grid(full, h, finished, roi, 2);
  int clamped = 0, renormalised = 0, to_normal = 0;
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      const float v = gray_plain.at<float>(y, x);
      const cv::Vec3f b = vector_plain.at<cv::Vec3f>(y, x), f = vector_finished.at<cv::Vec3f>(y, x);
      if (!roi.contains({x, y})) {
        EXPECT_EQ(gray_finished.at<float>(y, x), -3.0f);
        EXPECT_EQ(f, cv::Vec3f(-3, -3, -3));
        continue;
      }
      if (!g.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(gray_finished.at<float>(y, x), 1.0f) << "the background 7, clamped";
        EXPECT_EQ(f, cv::Vec3f(0, 0, 0));
        continue;
      }
      EXPECT_EQ(gray_finished.at<float>(y, x), std::clamp(v, 0.0f, 1.0f));
      clamped += v < 0.0f || v > 1.0f;
      const float len = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);  // in float, as the finish
      if (len > 1e-12f) {
        EXPECT_EQ(f, b * (1.0f / len));
        EXPECT_NEAR(cv::norm(f), 1.0, 1e-5);
        ++renormalised;
      } else {
        EXPECT_EQ(f, g.normal_view.at<cv::Vec3f>(y, x));
        ++to_normal;
      }
    }
  EXPECT_GT(clamped, 100);
  EXPECT_GT(renormalised, 5000);
  EXPECT_GT(to_normal, 20);
}

// The header's formulas pixel by pixel, in the order the per-pixel code evaluates them
// (the weights and upsample run 8 pixels at a time where they can; those lanes must give
// these bits). The frame's depths span three decades so that exp's argument runs from 0
// past its underflow, and its mask leaves texels and pixels of every kind of neighbourhood.
TEST(HalfResolution, WeightsAndUpsampleGiveTheBitsOfThePerPixelFormulas) {
  const cv::Size size(203, 37);
  cv::Mat depth(size, CV_32FC1), normal(size, CV_32FC3), mask(size, CV_8UC1);
  cv::RNG rng(7);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      const bool foreground = rng.uniform(0.0, 1.0) < 0.85;
      mask.at<uint8_t>(y, x) = foreground ? 255 : 0;
      depth.at<float>(y, x) = foreground ? float(std::pow(10.0, rng.uniform(-1.0, 2.0))) : std::numeric_limits<float>::infinity();
      cv::Vec3f n(float(rng.uniform(-1.0, 1.0)), float(rng.uniform(-1.0, 1.0)), float(rng.uniform(0.05, 1.0)));
      normal.at<cv::Vec3f>(y, x) = foreground ? n / cv::norm(n) : cv::Vec3f(0, 0, 0);
    }
  const cv::Mat no_positions;
  Camera camera;
  camera.width_px = size.width;
  camera.height_px = size.height;
  const FullGrid full{depth, normal, no_positions, mask, camera};
  HalfGrid h;
  build_half_grid(full, h, 2);
  // One image of each channel count the upsample takes (1 to 4), their channels' texels
  // side by side in `texel` (channels 0, 1-3, 4-5, 6-9).
  cv::Mat gray(h.depth_view.size(), CV_32FC1), color(h.depth_view.size(), CV_32FC3);
  cv::Mat pair(h.depth_view.size(), CV_32FC2), quad(h.depth_view.size(), CV_32FC4);
  for (cv::Mat* m : {&gray, &color, &pair, &quad}) cv::randu(*m, -1.0f, 2.0f);
  cv::Mat up_gray(size, CV_32FC1), up_color(size, CV_32FC3), up_pair(size, CV_32FC2), up_quad(size, CV_32FC4);
  const UpsampleImage images[] = {{gray, up_gray, cv::Scalar(7.0), cv::Scalar(9.0)},
                                  {color, up_color, cv::Scalar(1, 2, 3), cv::Scalar(4, 5, 6)},
                                  {pair, up_pair, cv::Scalar(1, 2), cv::Scalar(3, 4)},
                                  {quad, up_quad, cv::Scalar(1, 2, 3, 4), cv::Scalar(5, 6, 7, 8)}};
  const cv::Mat half_images[] = {gray, color, pair, quad}, full_images[] = {up_gray, up_color, up_pair, up_quad};
  // Channel c of the images side by side (texel or pixel (x, y) of each image).
  const auto channel = [](std::span<const cv::Mat> side_by_side, int y, int x, int c) {
    for (const cv::Mat& m : side_by_side) {
      if (c < m.channels()) return m.ptr<float>(y)[x * m.channels() + c];
      c -= m.channels();
    }
    return 0.0f;
  };
  const auto texel = [&](int j, int i, int c) { return channel(half_images, j, i, c); };
  const auto pixel = [&](int y, int x, int c) { return channel(full_images, y, x, c); };
  constexpr int kChannels = 10;
  upsample_from_half_grid(full, h, images, cv::Rect(0, 0, size.width, size.height), 2);

  const int hw = h.depth_view.cols, hh = h.depth_view.rows;
  int blended = 0, underflowed = 0;
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      if (!mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(up_gray.at<float>(y, x), 7.0f);
        continue;
      }
      const float fx = (float(x) + 0.5f) * 0.5f - 0.5f, fy = (float(y) + 0.5f) * 0.5f - 0.5f;
      const int tx = int(std::floor(fx)), ty = int(std::floor(fy));
      const float ax = fx - float(tx), ay = fy - float(ty);
      const float d = depth.at<float>(y, x);
      const cv::Vec3f n = normal.at<cv::Vec3f>(y, x);
      const float inv_tol = 1.0f / (0.05f * d);
      float ref[4], wsum = 0.0f, acc[kChannels] = {};
      for (int k = 0; k < 4; ++k) {
        const int i = std::clamp(tx + (k & 1), 0, hw - 1), j = std::clamp(ty + (k >> 1), 0, hh - 1);
        ref[k] = 0.0f;
        if (!h.mask.at<uint8_t>(j, i)) continue;
        const float wb = ((k & 1) ? ax : 1.0f - ax) * ((k >> 1) ? ay : 1.0f - ay);
        const float dz = std::abs(h.depth_view.at<float>(j, i) - d) * inv_tol;
        if (dz > 88.0f) ++underflowed;
        float c = std::max(0.0f, n.dot(h.normal_view.at<cv::Vec3f>(j, i)));
        c *= c;
        ref[k] = wb * upsample_depth_falloff(-dz) * c * c;
      }
      for (int k = 0; k < 4; ++k) wsum += ref[k];
      if (!(wsum > 1e-4f)) continue;  // nearest in depth (UpsampleKeepsConstants...)
      ++blended;
      for (int k = 0; k < 4; ++k) {
        if (ref[k] == 0.0f) continue;
        const int i = std::clamp(tx + (k & 1), 0, hw - 1), j = std::clamp(ty + (k >> 1), 0, hh - 1);
        for (int c = 0; c < kChannels; ++c) acc[c] += ref[k] * texel(j, i, c);
      }
      const float inv_wsum = 1.0f / wsum;  // one division per pixel, every channel multiplied
      for (int c = 0; c < kChannels; ++c)
        EXPECT_EQ(std::bit_cast<uint32_t>(pixel(y, x, c)), std::bit_cast<uint32_t>(acc[c] * inv_wsum)) << c;
    }
  EXPECT_GT(blended, size.area() / 4);
  EXPECT_GT(underflowed, 100);
}

// The weights' depth term is exp within 2 ulp on [-87, 0] (its own polynomials, the same on
// every instruction set: a Taylor polynomial above -0.1, Cephes' below), and exp(-87)
// below: small, positive and a normal float.
TEST(HalfResolution, DepthFalloffIsExpWithinTwoUlp) {
  int max_ulp = 0;
  for (int i = 0; i <= 400000; ++i) {
    // Every 4.35e-4 over the range, and every 5e-7 over [-0.1, 0] (the Taylor polynomial's).
    const float x = i <= 200000 ? -87.0f * float(i) / 200000.0f : -0.1f * float(i - 200000) / 200000.0f;
    const float exact = float(std::exp(double(x)));
    const float got = upsample_depth_falloff(x);
    max_ulp = std::max(max_ulp, std::abs(int(std::bit_cast<uint32_t>(got)) - int(std::bit_cast<uint32_t>(exact))));
  }
  EXPECT_LE(max_ulp, 2);
  EXPECT_EQ(upsample_depth_falloff(0.0f), 1.0f);
  EXPECT_EQ(upsample_depth_falloff(-200.0f), upsample_depth_falloff(-87.0f));
  EXPECT_GE(upsample_depth_falloff(-200.0f), std::numeric_limits<float>::min());
  EXPECT_LT(upsample_depth_falloff(-200.0f), 1e-37f);
}

TEST(HalfResolution, SampleAtTexelsTakesEachTexelsSourcePixel) {
  const GBuffer g = frame();
  const FullGrid full{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
  HalfGrid plain;
  build_half_grid(full, plain, 1);
  cv::Mat sampled;
  sample_at_texels(plain, g.albedo, sampled, 2);
  ASSERT_EQ(sampled.size(), cv::Size(81, 46));
  // The source pixel's value; texels that took no pixel hold 0.
  int taken = 0;
  for (int j = 0; j < 46; ++j)
    for (int i = 0; i < 81; ++i) {
      const cv::Vec2i src = plain.source.at<cv::Vec2i>(j, i);
      if (src[0] < 0) {
        EXPECT_EQ(sampled.at<cv::Vec3f>(j, i), cv::Vec3f(0, 0, 0));
        continue;
      }
      ++taken;
      EXPECT_EQ(sampled.at<cv::Vec3f>(j, i), g.albedo.at<cv::Vec3f>(src[1], src[0]));
    }
  EXPECT_GT(taken, 81 * 46 / 2);
}

// The terms of one frame computed together (one grid, one upsample) return the bits each
// returns computed alone, at half resolution and with a term at full resolution.
TEST(HalfResolution, TermsComputedTogetherGiveTheBitsOfEachAlone) {
  const GBuffer g = frame();
  AoSettings ao_settings = ao_preset(AoMethod::gtao, Preset::low);
  ao_settings.multibounce = true;
  const Environment sky = Environment::sky(SkyGradient{});
  const SsdoSettings ssdo_settings = ssdo_preset(SsdoMethod::ssdo, Preset::low);
  ConfidenceSettings cs;
  const AoInputs ao_in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &g.albedo};
  const SsdoInputs ssdo_in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, sky, &g.albedo};
  for (const int ao_divisor : {2, 1}) {
    ao_settings.resolution_divisor = ao_divisor;
    AoOutput ao;
    SsdoOutput light;
    cv::Mat confidence;
    compute_ao_at_resolution(ao_in, ao_settings, ao, {}, 2);
    compute_ssdo_at_resolution(ssdo_in, ssdo_settings, light, {}, 2);
    compute_confidence_at_resolution(g.depth_view, g.normal_view, g.mask, g.camera, cs, confidence, {}, 2);
    EXPECT_LT(cv::mean(ao.ao)[0], 0.99);  // something is occluded
    EXPECT_GT(cv::mean(light.indirect)[0], 0.0);
    EXPECT_LT(cv::mean(confidence)[0], 1.0);

    const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &sky, &g.albedo};
    TermOutputs together;
    compute_terms(in, {&ao_settings, &ssdo_settings, &cs}, together, {}, 2);
    EXPECT_EQ(cv::norm(ao.ao, together.ao.ao, cv::NORM_INF), 0.0) << ao_divisor;
    EXPECT_EQ(cv::norm(ao.bent_normal_view, together.ao.bent_normal_view, cv::NORM_INF), 0.0) << ao_divisor;
    EXPECT_EQ(cv::norm(light.direct, together.ssdo.direct, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(light.indirect, together.ssdo.indirect, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(confidence, together.confidence, cv::NORM_INF), 0.0);
  }
}

// With TermSettings::denoise, the denoised AO and SSDO terms are the upsample of the
// grid's terms denoised on the grid (its guides, the settings in texels), finished as the
// raw ones; the raw terms keep their bits; and a roi gets the bits of the whole frame's
// pixels there (the grid's terms are computed as far as the denoise's taps reach).
TEST(HalfResolution, TermsDenoisedOnTheGridAreTheUpsampleOfTheGridsDenoise) {
  FrameGrids f;
  const GBuffer& g = f.g;
  const AoSettings ao_settings = ao_preset(AoMethod::gtao, Preset::low);
  const SsdoSettings ssdo_settings = ssdo_preset(SsdoMethod::ssdo, Preset::low);
  ASSERT_TRUE(runs_on_half_grid(ao_settings) && runs_on_half_grid(ssdo_settings));
  const Environment sky = Environment::sky(SkyGradient{});
  const DenoiseSettings ds;
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &sky, &g.albedo};
  TermOutputs plain, denoised;
  compute_terms(in, {&ao_settings, &ssdo_settings}, plain, {}, 2);
  compute_terms(in, {&ao_settings, &ssdo_settings, nullptr, &ds}, denoised, {}, 2);
  EXPECT_TRUE(plain.denoised.ao.empty());
  EXPECT_EQ(cv::norm(plain.ao.ao, denoised.ao.ao, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(plain.ssdo.direct, denoised.ssdo.direct, cv::NORM_INF), 0.0);

  // The definition, from the kernels on the grid.
  AoOutput ao;
  compute_ao({f.h.depth_view, f.h.normal_view, f.h.position_view, f.h.mask, f.h.camera}, ao_settings, ao, {}, 2);
  cv::Mat albedo;
  sample_at_texels(f.h, g.albedo, albedo, 2);
  SsdoOutput light;
  compute_ssdo({f.h.depth_view, f.h.normal_view, f.h.position_view, f.h.mask, f.h.camera, sky, &albedo},
               ssdo_settings, light, {}, 2);
  cv::Mat grid_ao, grid_direct, grid_indirect;
  const cv::Mat* noisy[] = {&ao.ao, &light.direct, &light.indirect};
  cv::Mat* smooth[] = {&grid_ao, &grid_direct, &grid_indirect};
  denoise_bilateral(noisy, f.h.depth_view, f.h.normal_view, f.h.mask, ds, smooth, {}, 2);
  cv::Mat want_ao(g.depth_view.size(), CV_32FC1), want_direct(g.depth_view.size(), CV_32FC3),
      want_indirect(g.depth_view.size(), CV_32FC3);
  const UpsampleImage images[] = {
      {grid_ao, want_ao, cv::Scalar(1.0), cv::Scalar(1.0), UpsampleFinish::clamp_unit_interval},
      {grid_direct, want_direct, cv::Scalar::all(0), cv::Scalar::all(0)},
      {grid_indirect, want_indirect, cv::Scalar::all(0), cv::Scalar::all(0)}};
  upsample_from_half_grid(f.full, f.h, images, cv::Rect(cv::Point(), g.depth_view.size()), 2);
  EXPECT_EQ(cv::norm(denoised.denoised.ao, want_ao, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(denoised.denoised.direct, want_direct, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(denoised.denoised.indirect, want_indirect, cv::NORM_INF), 0.0);
  // The denoise did something: neighbouring pixels differ less than in the raw term.
  auto variation = [&](const cv::Mat& m) {
    const int w = m.cols - 1;
    return cv::norm(m(cv::Rect(1, 0, w, m.rows)), m(cv::Rect(0, 0, w, m.rows)), cv::NORM_L1);
  };
  EXPECT_LT(variation(denoised.denoised.ao), 0.8 * variation(denoised.ao.ao));

  const cv::Rect r(37, 21, 50, 33);
  TermOutputs part;
  compute_terms(in, {&ao_settings, &ssdo_settings, nullptr, &ds}, part, r, 2);
  EXPECT_EQ(cv::norm(part.denoised.ao(r), denoised.denoised.ao(r), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(part.denoised.direct(r), denoised.denoised.direct(r), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(part.ao.ao(r), denoised.ao.ao(r), cv::NORM_INF), 0.0);
}

// The grid terms kept for a later step (TermSettings::keep_grid_terms) are the kernels' own
// on the grid, not upsampled; finish_half_grid_terms of them gives the bits compute_terms
// gives with its denoise on the grid; of other values to denoise (a shot's filtered terms),
// their own denoise, beside the same raw terms.
TEST(HalfResolution, KeptGridTermsFinishedLaterGiveTheBitsOfComputeTerms) {
  FrameGrids f;
  const GBuffer& g = f.g;
  const AoSettings ao_settings = ao_preset(AoMethod::gtao, Preset::low);
  const SsdoSettings ssdo_settings = ssdo_preset(SsdoMethod::ssdo, Preset::low);
  const Environment sky = Environment::sky(SkyGradient{});
  const DenoiseSettings ds;
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &sky, &g.albedo};
  TermSettings keep{&ao_settings, &ssdo_settings};
  keep.keep_grid_terms = true;
  keep.stored_in_half = {true, true};
  TermSettings at_once{&ao_settings, &ssdo_settings, nullptr, &ds};
  at_once.stored_in_half = {true, true};
  TermOutputs kept, denoised;
  compute_terms(in, keep, kept, {}, 2);
  compute_terms(in, at_once, denoised, {}, 2);
  ASSERT_FALSE(kept.grid.empty());
  EXPECT_TRUE(kept.ao.ao.empty() && kept.ssdo.direct.empty());  // not upsampled
  EXPECT_EQ(test::max_difference(kept.ao.bent_normal_view, denoised.ao.bent_normal_view), 0.0);
  EXPECT_EQ(kept.grid.ao.size(), f.h.depth_view.size());
  EXPECT_EQ(cv::norm(kept.grid.grid.depth_view, f.h.depth_view, cv::NORM_INF), 0.0);
  EXPECT_TRUE(kept.grid.grid.position_view.empty());
  EXPECT_TRUE(denoised.grid.empty());  // kept only when asked
  AoOutput ao;
  compute_ao({f.h.depth_view, f.h.normal_view, f.h.position_view, f.h.mask, f.h.camera}, ao_settings, ao, {}, 2);
  EXPECT_EQ(cv::norm(kept.grid.ao, ao.ao, cv::NORM_INF), 0.0);

  finish_half_grid_terms(f.full, kept.grid, kept.grid, ds, {true, true}, kept, 2);
  EXPECT_EQ(cv::norm(kept.ao.ao, denoised.ao.ao, cv::NORM_INF), 0.0);
  ASSERT_EQ(kept.ssdo.direct.type(), CV_16FC3);
  EXPECT_EQ(test::max_difference(kept.ssdo.direct, denoised.ssdo.direct), 0.0);
  EXPECT_EQ(test::max_difference(kept.ssdo.indirect, denoised.ssdo.indirect), 0.0);
  EXPECT_EQ(cv::norm(kept.denoised.ao, denoised.denoised.ao, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(kept.denoised.direct, denoised.denoised.direct, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(kept.denoised.indirect, denoised.denoised.indirect, cv::NORM_INF), 0.0);

  // Other values to denoise: AO a constant 0.25 stays 0.25 on foreground and 1 on
  // background (the upsample's AO background); the raw AO is upsampled as before.
  TermSettings ao_only{&ao_settings};
  ao_only.keep_grid_terms = true;
  TermOutputs mine;
  compute_terms(in, ao_only, mine, {}, 2);
  HalfGridTerms constant;
  constant.grid = mine.grid.grid;
  constant.ao = cv::Mat(f.h.depth_view.size(), CV_32FC1, cv::Scalar(0.25f));
  finish_half_grid_terms(f.full, mine.grid, constant, ds, {}, mine, 2);
  EXPECT_TRUE(mine.denoised.direct.empty() && mine.ssdo.direct.empty());
  EXPECT_EQ(cv::norm(mine.ao.ao, denoised.ao.ao, cv::NORM_INF), 0.0);
  double lo = 0, hi = 0;
  cv::minMaxLoc(mine.denoised.ao, &lo, &hi, nullptr, nullptr, g.mask);
  EXPECT_NEAR(lo, 0.25, 1e-6);
  EXPECT_NEAR(hi, 0.25, 1e-6);
  cv::minMaxLoc(mine.denoised.ao, &lo, &hi, nullptr, nullptr, g.mask == 0);
  EXPECT_EQ(lo, 1.0);
  EXPECT_EQ(hi, 1.0);
}

// max_radius_px counts pixels of the picture on either grid: a method on the half grid
// gets half as many texels, so it reaches as far as on the full grid. The bound here (6 px)
// is below the radius' projection on every pixel, so the texels it gives change the bits.
TEST(HalfResolution, RadiusBoundCountsPixelsOfThePicture) {
  FrameGrids f;
  const GBuffer& g = f.g;
  AoSettings ao_settings = ao_preset(AoMethod::gtao, Preset::low);
  ao_settings.max_radius_px = 6.0f;
  TermSettings keep{&ao_settings};
  keep.keep_grid_terms = true;
  TermOutputs kept;
  compute_terms({g.depth_view, g.normal_view, g.position_view, g.mask, g.camera}, keep, kept, {}, 2);
  ASSERT_FALSE(kept.grid.ao.empty());
  const AoInputs grid{f.h.depth_view, f.h.normal_view, f.h.position_view, f.h.mask, f.h.camera};
  AoOutput in_texels, in_pixels;
  AoSettings on_grid = ao_settings;
  on_grid.max_radius_px = 3.0f;
  compute_ao(grid, on_grid, in_texels, {}, 2);
  compute_ao(grid, ao_settings, in_pixels, {}, 2);
  EXPECT_EQ(cv::norm(kept.grid.ao, in_texels.ao, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(kept.grid.ao, in_pixels.ao, cv::NORM_INF), 0.01);
  // Farther taps find more occluders: the grid's 6 texels would reach 12 pixels.
  EXPECT_LT(cv::mean(in_pixels.ao, f.h.mask)[0], cv::mean(in_texels.ao, f.h.mask)[0] - 0.01);
  // The least valid bound, 2 pixels, stays 2 texels on the grid (a valid setting there).
  EXPECT_EQ(max_radius_on_grid(2.0f, 2), 2.0f);
  EXPECT_EQ(max_radius_on_grid(512.0f, 2), 256.0f);
  EXPECT_EQ(max_radius_on_grid(512.0f, 1), 512.0f);
  ao_settings.max_radius_px = 2.0f;
  TermOutputs smallest;
  compute_terms({g.depth_view, g.normal_view, g.position_view, g.mask, g.camera}, keep, smallest, {}, 2);
  on_grid.max_radius_px = 2.0f;
  compute_ao(grid, on_grid, in_texels, {}, 2);
  EXPECT_EQ(cv::norm(smallest.grid.ao, in_texels.ao, cv::NORM_INF), 0.0);
}

// Without full-resolution positions the grid computes its texels' own from depth: the
// bits of view_positions_from_depth at the source pixels, so kernels on the grid return
// the bits they return given the full-resolution positions computed from depth.
TEST(HalfResolution, TexelPositionsFromDepthGiveTheBitsOfFullResolutionPositions) {
  const GBuffer g = frame();
  cv::Mat from_depth;
  view_positions_from_depth(g.depth_view, g.mask, g.camera, from_depth, {}, 2);
  const cv::Mat none;
  HalfGrid given, computed, without;
  build_half_grid({g.depth_view, g.normal_view, from_depth, g.mask, g.camera}, given, 2);
  build_half_grid({g.depth_view, g.normal_view, none, g.mask, g.camera}, computed, 2);
  build_half_grid({g.depth_view, g.normal_view, none, g.mask, g.camera}, without, 2, false);
  ASSERT_EQ(computed.position_view.size(), given.position_view.size());
  EXPECT_EQ(cv::norm(computed.position_view, given.position_view, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(computed.position_view, cv::NORM_INF), 1.0);  // not all zero
  EXPECT_TRUE(without.position_view.empty());
  // Without positions, the same texels.
  EXPECT_EQ(cv::norm(without.depth_view, given.depth_view, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(without.normal_view, given.normal_view, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(without.mask, given.mask, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(without.source, given.source, cv::NORM_INF), 0.0);

  const AoSettings ao_settings = ao_preset(AoMethod::gtao, Preset::low);
  AoOutput with_positions, without_positions;
  compute_ao_at_resolution({g.depth_view, g.normal_view, from_depth, g.mask, g.camera}, ao_settings, with_positions,
                           {}, 2);
  compute_ao_at_resolution({g.depth_view, g.normal_view, none, g.mask, g.camera}, ao_settings, without_positions,
                           {}, 2);
  EXPECT_EQ(cv::norm(with_positions.ao, without_positions.ao, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(with_positions.bent_normal_view, without_positions.bent_normal_view, cv::NORM_INF), 0.0);

  const Environment sky = Environment::sky(SkyGradient{});
  const SsdoSettings ssdo_settings = ssdo_preset(SsdoMethod::ssdo, Preset::low);
  SsdoOutput lit_with, lit_without;
  compute_ssdo_at_resolution({g.depth_view, g.normal_view, from_depth, g.mask, g.camera, sky, &g.albedo},
                             ssdo_settings, lit_with, {}, 2);
  compute_ssdo_at_resolution({g.depth_view, g.normal_view, none, g.mask, g.camera, sky, &g.albedo},
                             ssdo_settings, lit_without, {}, 2);
  EXPECT_EQ(cv::norm(lit_with.direct, lit_without.direct, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(lit_with.indirect, lit_without.indirect, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::mean(lit_with.indirect)[0], 0.0);
}

TEST(HalfResolution, RoiOfTheHalfGridCoversEveryTexelTheUpsampleReads) {
  const cv::Size size(161, 91);
  const cv::Rect half_all(0, 0, 81, 46);
  for (const cv::Rect r : {cv::Rect(0, 0, 161, 91), cv::Rect(37, 21, 50, 33), cv::Rect(160, 90, 1, 1)}) {
    const cv::Rect h = half_grid_roi(r, size);
    EXPECT_EQ(h & half_all, h);
    // Pixel x reads texels floor(x / 2 - 0.25) - 1 .. + 2, clamped to the grid.
    for (int x : {r.x, r.x + r.width - 1}) {
      const int lo = std::max(0, int(std::floor(x / 2.0 - 0.25)) - 1), hi = std::min(80, int(std::floor(x / 2.0 - 0.25)) + 2);
      EXPECT_LE(h.x, lo);
      EXPECT_GE(h.x + h.width - 1, hi);
    }
  }
}

}  // namespace
}  // namespace ssdo
