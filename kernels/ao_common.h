// Internal helpers shared by the screen-space AO methods (ao_hemisphere.cpp, ao_hbao.cpp,
// ao_gtao.cpp): the projected radius, the distance falloff, the per-pixel view vector,
// the slice frame of a screen direction, a fast acos and the multi-bounce fit.
// Header-only and inline so the per-pixel loops see through every call.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include <glm/glm.hpp>
#include <opencv2/core.hpp>

#include "kernels/ao.h"
#include "core/camera.h"

namespace ssdo::detail {

// pi / 2 in float (halving is exact: the float nearest pi / 2).
inline constexpr float kHalfPi = std::numbers::pi_v<float> / 2.0f;

// Taps closer than this to the centre pixel are skipped, pixels: the centre pixel itself
// carries no occlusion information (its own depth), and a tap at distance < 1 px rounds
// back onto it (XeGTAO's "pixelTooCloseThreshold" plays the same role).
inline constexpr float kMinTapDistancePx = 1.0f;

// Radius of the occlusion sphere projected to pixels at planar depth depth_view: the
// geometric mean of the x and y scales (equal for square pixels), clamped to
// [0, max_radius_px] so close-up pixels cost at most max_radius_px of marching.
inline float projected_radius_px(const Camera& camera, float depth_view, float radius_world,
                                 float max_radius_px) {
  const glm::vec2 ppu = camera.pixels_per_unit(depth_view);
  const float r = radius_world * std::sqrt(ppu.x * ppu.y);
  return std::min(r, max_radius_px);
}

// Distance falloff (as XeGTAO's falloffMul/falloffAdd): weight 1 up to
// (1 - falloff_fraction) * radius, linear to 0 at radius, 0 beyond. falloff_fraction = 0
// is the hard cut of Cycles' AO distance: weight = (dist <= radius).
struct Falloff {
  float mul = 0.0f;
  float add = 1.0f;
  float radius = 0.0f;
  bool hard = true;

  Falloff(float radius_world, float falloff_fraction) : radius(radius_world) {
    const float range = falloff_fraction * radius_world;
    // Below 1e-6 of the radius the ramp is narrower than float resolution of a distance
    // near the radius: treat it as the hard cut (avoids dividing by ~0).
    hard = !(range > 1e-6f * radius_world);
    if (!hard) {
      mul = -1.0f / range;
      add = radius_world / range;
    }
  }
  float operator()(float dist) const {
    if (hard) return dist <= radius ? 1.0f : 0.0f;
    return std::clamp(dist * mul + add, 0.0f, 1.0f);
  }
};

// Unit vector from a view-space surface point towards the eye (perspective) or +Z
// (orthographic): the true per-pixel view vector, not a fixed axis.
inline glm::vec3 view_vector(const Camera& camera, const glm::vec3& p_view) {
  if (!camera.is_perspective()) return {0.0f, 0.0f, 1.0f};
  return glm::normalize(-p_view);
}

// Scales from a screen-space direction (pixels, y down) to the direction of the same line
// in view space near the image plane: +x_px = +x_view and +y_px = -y_view, divided by the
// projection's scale terms (non-square pixels and anisotropic projections stay exact).
struct ScreenToView {
  float sx = 1.0f;
  float sy = 1.0f;
  explicit ScreenToView(const Camera& camera)
      : sx(1.0f / (float(camera.width_px) * std::abs(camera.view_to_clip[0][0]))),
        sy(-1.0f / (float(camera.height_px) * std::abs(camera.view_to_clip[1][1]))) {}
  glm::vec3 operator()(float dx_px, float dy_px) const { return {dx_px * sx, dy_px * sy, 0.0f}; }
};

// acos with absolute error < 7e-5 rad on [-1, 1] (Abramowitz & Stegun 4.4.45, the
// third-order polynomial in sqrt(1 - |x|)); called once per tap and per slice.
inline float fast_acos(float x) {
  const float ax = std::min(std::abs(x), 1.0f);
  float r = ((-0.0187293f * ax + 0.0742610f) * ax - 0.2121144f) * ax + 1.5707288f;
  r *= std::sqrt(1.0f - ax);
  return x >= 0.0f ? r : std::numbers::pi_v<float> - r;
}

// The plane through the eye that contains the screen line through the pixel in direction
// (dx_px, dy_px): every tap on that screen line lies in it (Jimenez et al. 2016, Alg. 1
// lines 8-15). direction: unit, orthogonal to view, pointing to the +screen side; axis:
// the plane's unit normal; projected_normal: the normal projected into the plane.
struct Slice {
  glm::vec3 direction;
  glm::vec3 axis;
  float projected_normal_length;  // |N projected into the slice plane|
  float cos_n;                    // cos of the angle n between projected normal and view
  float n;                        // signed angle n (positive towards +direction), radians
};

inline Slice make_slice(const glm::vec3& screen_dir_view, const glm::vec3& view,
                        const glm::vec3& normal) {
  Slice s;
  glm::vec3 d = screen_dir_view - glm::dot(screen_dir_view, view) * view;
  s.direction = glm::normalize(d);
  s.axis = glm::normalize(glm::cross(s.direction, view));
  const glm::vec3 pn = normal - s.axis * glm::dot(normal, s.axis);
  s.projected_normal_length = glm::length(pn);
  // A normal along the axis has no projection: any n is equally valid; the slice then
  // contributes with weight 0 (projected_normal_length = 0), the guard only avoids 0/0.
  const float inv = s.projected_normal_length > 1e-12f ? 1.0f / s.projected_normal_length : 0.0f;
  s.cos_n = std::clamp(glm::dot(pn, view) * inv, -1.0f, 1.0f);
  const float sign = glm::dot(pn, s.direction) < 0.0f ? -1.0f : 1.0f;
  // fast_acos: its 7e-5 rad is far below the slices' sampling error, and every use of n
  // (limits, measures, intervals) shares it, so an open surface still integrates to 1.
  s.n = sign * fast_acos(s.cos_n);
  return s;
}

// Cosine-weighted slice measure of [0, h] (h signed; the weight of the side h lies on):
// GTAO eq. 10's inner integral, written with cos h = c (s = sin h, sign of h).
inline float inner_integral(float h, float c, float s, float cos_n, float sin_n) {
  // cos(2h - n) = cos 2h cos n + sin 2h sin n.
  const float cos_2h_n = (2.0f * c * c - 1.0f) * cos_n + 2.0f * s * c * sin_n;
  return 0.25f * (cos_n + 2.0f * h * sin_n - cos_2h_n);
}

inline float inner_integral(float h, float cos_n, float sin_n) {
  return inner_integral(h, std::cos(h), std::sin(h), cos_n, sin_n);
}

// Antiderivatives of cos(t - n)|sin t| cos t (A) and cos(t - n)|sin t| sin t (B) on t >= 0
// (the same expressions give the t < 0 side's integrals from 0, see the bent normal).
inline float bent_a(float c, float s, float cos_n, float sin_n) {
  return (-cos_n * c * c * c + sin_n * s * s * s) * (1.0f / 3.0f);
}
inline float bent_b(float c, float s, float cos_n, float sin_n) {
  return (cos_n * s * s * s + sin_n * (c * c * c - 3.0f * c)) * (1.0f / 3.0f);
}

// Nearest integer, halves away from zero (std::lround's rule), without the library call
// std::lround is: truncation of v + 0.5 sign(v). Exact for |v| < 2^22 except within one
// float step below a half, where the sum rounds up (a tap offset then moves by one pixel,
// as a different jitter would). Tap offsets are a few thousand pixels at most.
inline int round_to_int(float v) { return int(v + std::copysign(0.5f, v)); }

// Multi-bounce fit (Jimenez et al. 2016, eq. 10): the visibility with interreflections
// for albedo rho, a cubic in the one-bounce visibility, never below it.
inline float multibounce(float visibility, float albedo) {
  const float a = 2.0404f * albedo - 0.3324f;
  const float b = -4.7951f * albedo + 0.6417f;
  const float c = 2.7552f * albedo + 0.6903f;
  const float x = visibility;
  return std::max(x, ((x * a + b) * x + c) * x);
}

// Scalar albedo for the multi-bounce fit: Rec. 709 luminance of linear RGB, in [0, 1].
inline float albedo_luminance(const cv::Vec3f& rgb) {
  return std::clamp(0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2], 0.0f, 1.0f);
}

// Depth bias along the normal, scene units: depth_bias_relative * depth_view. Why along
// the normal: taps on the pixel's own (planar) surface then lie strictly below the
// tangent plane, so float rounding of positions cannot create self-occlusion at any
// viewing angle (grazing included); relative to depth because position error grows
// with depth (float and half-float alike).
inline glm::vec3 biased_origin(const glm::vec3& p_view, const glm::vec3& normal,
                               float depth_view, float depth_bias_relative) {
  return p_view + normal * (depth_bias_relative * depth_view);
}

inline glm::vec3 load3(const cv::Mat& m, int x, int y) {
  const cv::Vec3f& v = m.ptr<cv::Vec3f>(y)[x];
  return {v[0], v[1], v[2]};
}

}  // namespace ssdo::detail
