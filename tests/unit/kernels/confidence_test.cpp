// The confidence term (kernels/confidence.h) against its per-pixel reference.
#include "kernels/confidence.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "kernels/denoise.h"
#include "kernels/noise.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

// The definition of confidence.h evaluated one pixel and one tap at a time, in the order
// the kernel evaluates each pixel (its operations in the same order, so the same bits):
// rays x(s) = o + s u affine in the pixel position, the chord of the hemisphere along the
// ray through each tap's centre, its part in front of the stored surface, and the ratio of
// the summed lengths.
cv::Mat reference_confidence(const GBuffer& g, const ConfidenceSettings& s) {
  const Camera& cam = g.camera;
  auto point = [&](float px, float py, float depth) {
    return cam.view_from_pixel_depth(glm::vec2(px, py), depth);
  };
  glm::vec3 o0(0.0f), ox(0.0f), oy(0.0f), u0(0.0f, 0.0f, -1.0f), ux(0.0f), uy(0.0f);
  if (cam.is_perspective()) {
    u0 = point(0.0f, 0.0f, 1.0f);
    ux = point(1.0f, 0.0f, 1.0f) - u0;
    uy = point(0.0f, 1.0f, 1.0f) - u0;
  } else {
    o0 = point(0.0f, 0.0f, 0.0f);
    ox = point(1.0f, 0.0f, 0.0f) - o0;
    oy = point(0.0f, 1.0f, 0.0f) - o0;
  }
  const int width = g.depth_view.cols, height = g.depth_view.rows;
  auto known = [&](int x, int y) {
    const float d = g.depth_view.at<float>(y, x);
    return g.mask.at<uint8_t>(y, x) != 0 && d > 0.0f && std::isfinite(d);
  };
  cv::Mat out(g.depth_view.size(), CV_32FC1, cv::Scalar(1.0f));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      if (!known(x, y)) continue;
      const float d = g.depth_view.at<float>(y, x);
      const float pxc = float(x) + 0.5f, pyc = float(y) + 0.5f;
      const glm::vec3 p = o0 + pxc * ox + pyc * oy + d * (u0 + pxc * ux + pyc * uy);
      const cv::Vec3f nv = g.normal_view.at<cv::Vec3f>(y, x);
      const glm::vec3 n(nv[0], nv[1], nv[2]);
      const glm::vec2 ppu = cam.pixels_per_unit(d);
      float radius = s.radius_world;
      const float radius_px_max = radius * std::max(ppu.x, ppu.y);
      if (radius_px_max > s.max_radius_px) radius *= s.max_radius_px / radius_px_max;
      // The pixel's rotation: noise01 turns (kernels/noise.h).
      float cos_r, sin_r;
      sincos_turns(noise01(x, y, 0, s.seed), cos_r, sin_r);
      double observed = 0.0, total = 0.0;
      for (int k = 0; k < s.taps; ++k) {
        // Vogel spiral: equal-area rings, golden-angle turns, rotated per pixel.
        const float rho = std::sqrt((float(k) + 0.5f) / float(s.taps));
        const float angle = float(k) * 2.39996322972865332f;
        const float vx = rho * std::cos(angle), vy = rho * std::sin(angle);
        const float tx = std::floor(pxc + radius * ppu.x * (cos_r * vx - sin_r * vy));
        const float ty = std::floor(pyc + radius * ppu.y * (sin_r * vx + cos_r * vy));
        const float cx = tx + 0.5f, cy = ty + 0.5f;
        const glm::vec3 f = (o0 + cx * ox + cy * oy) - p;
        const glm::vec3 u = u0 + cx * ux + cy * uy;
        const float a = glm::dot(u, u), b = glm::dot(u, f);
        const float c = glm::dot(f, f) - radius * radius;
        const float disc = b * b - a * c;
        if (!(disc > 0.0f)) continue;  // the ray misses the sphere
        const float root = std::sqrt(disc);
        float s0 = std::max((-b - root) / a, 0.0f), s1 = (-b + root) / a;
        const float nu = glm::dot(n, u), nf = glm::dot(n, f);
        if (nu == 0.0f && nf < 0.0f) continue;  // parallel to the tangent plane, below it
        if (nu < 0.0f) s1 = std::min(s1, -nf / nu);
        if (nu > 0.0f) s0 = std::max(s0, -nf / nu);
        if (!(s1 > s0)) continue;
        const float len_scale = std::sqrt(a);
        total += double((s1 - s0) * len_scale);
        const int ix = int(tx), iy = int(ty);
        if (ix < 0 || iy < 0 || ix >= width || iy >= height || !known(ix, iy)) continue;
        const float s_surface = g.depth_view.at<float>(iy, ix) * (1.0f + s.depth_bias_relative);
        const float seen = std::min(s1, s_surface) - s0;
        if (seen > 0.0f) observed += double(seen * len_scale);
      }
      out.at<float>(y, x) = total > 0.0 ? float(std::clamp(observed / total, 0.0, 1.0)) : 1.0f;
    }
  return out;
}

bool bitwise_equal(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

cv::Mat confidence_of(const GBuffer& g, const ConfidenceSettings& s, cv::Rect roi, int nthreads) {
  cv::Mat out;
  compute_confidence(g.depth_view, g.normal_view, g.mask, g.camera, s, out, roi, nthreads);
  return out;
}

// Settings of every evaluation below: every pixel (no half grid), the radius and tap
// counts of the call, a radius the max_radius_px bound shrinks near the camera.
ConfidenceSettings full_resolution(float radius_world, int taps) {
  ConfidenceSettings s;
  s.resolution_divisor = 1;
  s.radius_world = radius_world;
  s.taps = taps;
  s.max_radius_px = 24.0f;
  s.seed = 7;
  s.smoothing_radius_px = 0;  // the definition itself (the smoothing has tests of its own)
  return s;
}

// Mean |a - b| over the foreground of g.
double foreground_mae(const GBuffer& g, const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  return cv::mean(diff, g.mask)[0];
}

// Scenes with silhouettes, depth gaps and background; the camera sizes are odd and not
// multiples of the kernel's pixel batches.
TEST(Confidence, GivesTheReferenceBitsForAnyThreadCount) {
  const GBuffer scenes[] = {
      raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(163, 91), 0),
      raycast::render_gbuffer(raycast::poles_scene(), raycast::poles_camera(157, 89), 0)};
  for (const GBuffer& g : scenes)
    for (const ConfidenceSettings& s : {full_resolution(0.3f, 32), full_resolution(2.0f, 7)}) {
      const cv::Mat reference = reference_confidence(g, s);
      EXPECT_LT(cv::mean(reference)[0], 1.0);
      EXPECT_TRUE(bitwise_equal(confidence_of(g, s, {}, 1), reference));
      EXPECT_TRUE(bitwise_equal(confidence_of(g, s, {}, 3), reference));
      // A roi is written with the values of the whole image (taps read outside it).
      const cv::Rect roi(13, 9, 71, 40);
      const cv::Mat part = confidence_of(g, s, roi, 2);
      EXPECT_TRUE(bitwise_equal(part(roi), reference(roi)));
    }
}

TEST(Confidence, GivesTheReferenceBitsWithAnOrthographicCamera) {
  GBuffer g =
      raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(121, 67), 0);
  // The same depths and normals seen through parallel rays (a consistent frame is not
  // needed to compare two evaluations of it).
  g.camera.view_to_clip = glm::ortho(-3.0f, 3.0f, -1.7f, 1.7f, 0.1f, 100.0f);
  const ConfidenceSettings s = full_resolution(0.5f, 16);
  const cv::Mat reference = reference_confidence(g, s);
  EXPECT_LT(cv::mean(reference)[0], 1.0);
  EXPECT_TRUE(bitwise_equal(confidence_of(g, s, {}, 2), reference));
}

// The smoothing is the depth- and normal-aware blur (denoise_bilateral) of the fraction:
// the same bits as blurring the per-pixel reference, for any thread count, and in a roi
// (whose blur reads the fraction computed around it).
TEST(Confidence, SmoothingIsTheBlurOfTheFraction) {
  const GBuffer g = raycast::render_gbuffer(raycast::poles_scene(), raycast::poles_camera(157, 89), 0);
  ConfidenceSettings s = full_resolution(0.3f, 16);
  s.smoothing_radius_px = 2;
  const cv::Mat fraction = reference_confidence(g, full_resolution(0.3f, 16));
  cv::Mat expected;
  denoise_bilateral(fraction, g.depth_view, g.normal_view, g.mask, smoothing(s), expected, {}, 1);
  EXPECT_GT(cv::norm(expected, fraction, cv::NORM_INF), 0.01) << "the blur changes the fraction";
  EXPECT_TRUE(bitwise_equal(confidence_of(g, s, {}, 1), expected));
  EXPECT_TRUE(bitwise_equal(confidence_of(g, s, {}, 3), expected));
  for (const cv::Rect roi : {cv::Rect(13, 9, 71, 40), cv::Rect(0, 0, 30, 89), cv::Rect(150, 80, 7, 9)})
    EXPECT_TRUE(bitwise_equal(confidence_of(g, s, roi, 2)(roi), expected(roi))) << roi;
}

// Frames narrower or shorter than the blur's footprint, and rois at their edges: every
// value in [0, 1], the background 1, the same bits for any thread count.
TEST(Confidence, SmoothsFramesSmallerThanItsFootprint) {
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(2, 1), cv::Size(1, 5), cv::Size(4, 3), cv::Size(9, 2)}) {
    const GBuffer g = raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(size.width, size.height), 0);
    ConfidenceSettings s;
    s.radius_world = 0.5f;
    const cv::Mat whole = confidence_of(g, s, {}, 1);
    ASSERT_EQ(whole.size(), size);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        const float c = whole.at<float>(y, x);
        EXPECT_TRUE(c >= 0.0f && c <= 1.0f) << size << " " << x << "," << y << ": " << c;
        if (!g.mask.at<uint8_t>(y, x)) {
          EXPECT_EQ(c, 1.0f);
        }
      }
    EXPECT_TRUE(bitwise_equal(confidence_of(g, s, {}, 3), whole)) << size;
    const cv::Rect corner(size.width - 1, size.height - 1, 1, 1);
    EXPECT_TRUE(bitwise_equal(confidence_of(g, s, corner, 2)(corner), whole(corner))) << size;
  }
}

// Neighbours' tap patterns are rotated differently: 16 taps smoothed over radius 2 are
// closer to the fraction's limit (256 taps) than 32 taps alone, and 16 alone are farther.
TEST(Confidence, SixteenTapsSmoothedAreCloserToTheLimitThanThirtyTwo) {
  const GBuffer scenes[] = {
      raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(320, 180), 0),
      raycast::render_gbuffer(raycast::poles_scene(), raycast::poles_camera(320, 180), 0)};
  for (const GBuffer& g : scenes) {
    const cv::Mat limit = confidence_of(g, full_resolution(0.5f, 256), {}, 2);
    ConfidenceSettings smoothed = full_resolution(0.5f, 16);
    smoothed.smoothing_radius_px = ConfidenceSettings{}.smoothing_radius_px;
    const double mae_smoothed = foreground_mae(g, confidence_of(g, smoothed, {}, 2), limit);
    const double mae_32 = foreground_mae(g, confidence_of(g, full_resolution(0.5f, 32), {}, 2), limit);
    const double mae_16 = foreground_mae(g, confidence_of(g, full_resolution(0.5f, 16), {}, 2), limit);
    EXPECT_LT(mae_smoothed, 0.85 * mae_32) << "16 smoothed " << mae_smoothed << ", 32 " << mae_32;
    EXPECT_GT(mae_16, 1.3 * mae_32) << "16 " << mae_16 << ", 32 " << mae_32;
    EXPECT_GT(mae_32, 0.002) << "the scene has neighbourhoods the taps resolve only partly";
  }
}

// Thin posts 1.2 in front of a wall above a floor, seen from x = 0; views from x = +-1 see
// past the posts. Alone, the wall behind each post is hidden (the space behind a post's
// front is unknown); with the views most of it is observed.
TEST(Confidence, OtherViewsObserveWhatThisFrameHides) {
  raycast::Scene scene;
  scene.planes.push_back({{0.0f, 3.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, glm::vec3(0.8f)});
  scene.planes.push_back({{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, 1.0f}, glm::vec3(0.8f)});
  for (float x : {-1.2f, -0.4f, 0.4f, 1.2f})
    scene.boxes.push_back({{x, 1.8f, 0.0f}, {0.04f, 0.04f, 1.0f}, glm::mat3(1.0f), glm::vec3(0.8f)});
  auto camera_at = [](float x) {
    return raycast::look_at({x, -3.0f, 0.0f}, {x, 3.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 160, 90, 60.0f);
  };
  const GBuffer g = raycast::render_gbuffer(scene, camera_at(0.0f), 2);
  const std::vector<DepthView> views = {{camera_at(-1.0f), raycast::render_gbuffer(scene, camera_at(-1.0f), 2).depth_view, "left"},
                                        {camera_at(1.0f), raycast::render_gbuffer(scene, camera_at(1.0f), 2).depth_view, "right"}};
  ConfidenceSettings s;
  s.radius_world = 1.0f;
  cv::Mat alone, alone_no_views, seen_1, seen_2;
  compute_confidence(g.depth_view, g.normal_view, g.mask, g.camera, s, alone, {}, 2);
  compute_confidence(g.depth_view, g.normal_view, g.mask, g.camera, s, alone_no_views, {}, 2, ConfidenceViews{});
  compute_confidence(g.depth_view, g.normal_view, g.mask, g.camera, s, seen_1, {}, 1, {views, MultiViewSettings{}});
  compute_confidence(g.depth_view, g.normal_view, g.mask, g.camera, s, seen_2, {}, 2, {views, MultiViewSettings{}});
  ASSERT_EQ(cv::norm(alone, alone_no_views, cv::NORM_INF), 0.0) << "no views: the frame's own observation";
  ASSERT_EQ(std::memcmp(seen_1.data, seen_2.data, seen_1.total() * sizeof(float)), 0)
      << "the views' verdicts are filled on first use by whichever thread: the same bytes";
  // Views only add observers: no pixel loses confidence. Where the frame alone saw less
  // than 0.8 of the neighbourhood, the views observe most of the rest.
  double sum_alone = 0, sum_seen = 0;
  int hidden = 0;
  for (int y = 0; y < g.mask.rows; ++y)
    for (int x = 0; x < g.mask.cols; ++x) {
      const float a = alone.at<float>(y, x), v = seen_2.at<float>(y, x);
      EXPECT_GE(v, a) << x << "," << y;
      if (!g.mask.at<uint8_t>(y, x) || a >= 0.8f) continue;
      ++hidden, sum_alone += a, sum_seen += v;
    }
  ASSERT_GT(hidden, 500);
  EXPECT_GT(sum_seen / hidden, sum_alone / hidden + 0.15) << "alone " << sum_alone / hidden;
}

}  // namespace
}  // namespace ssdo
