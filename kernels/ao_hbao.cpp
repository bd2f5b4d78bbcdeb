// Horizon-based AO (HBAO): Bavoil, Sainz & Dimitrov 2008, "Image-Space Horizon-Based
// Ambient Occlusion" (SIGGRAPH talk; cited as "HBAO"), made to estimate the cosine-
// weighted quantity of the Cycles AO pass.
//
// Per pixel, `directions` screen directions (angle jittered per pixel) and `steps` taps
// per direction out to the projected radius (step offset jittered per pixel). For each
// direction, the horizon is the largest elevation of a tap above the pixel's tangent
// plane, taken from the normal (HBAO's tangent angle t is then 0: sin(t) = 0).
//
// Cosine weighting. HBAO's per-direction term sin(h) - sin(t) is the uniform solid-angle
// measure of the occluded elevations (HBAO eq. 3) in a direction's vertical plane. The
// taps of a screen direction do not lie in a vertical plane, though: they lie in the plane
// through the eye that contains the screen line (the GTAO slice; Jimenez et al. 2016,
// Alg. 1), whose highest direction is the projected normal, not the zenith. So each
// direction here is a half slice, and the occluded measure of slice angles beyond the
// horizon h (from the view vector) is the cosine-weighted slice measure of GTAO eq. 10:
//   m(h) = |pn| (cos n + 2 h sin n - cos(2 h - n)) / 4,  occluded = m(n + pi/2) - m(h),
// the analogue of sin(h) - sin(t) with the tangent t = n + pi/2 (the tangent plane from the
// normal). It is accumulated per tap with HBAO's attenuation (HBAO eq. 4, W = falloff):
//   occlusion(dir) = sum_i W(r_i) (m(h_{i-1}) - m(h_i)) over taps that raise the horizon,
// and AO = 1 - sum occlusion / sum m(n + pi/2) over directions (the half-slice weights
// |pn| also account for screen directions covering unequal azimuths around the normal;
// the ratio makes open surfaces exactly 1). Steps are uniform in distance (HBAO), with
// per-pixel jitter; directions cover [0, 2 pi) independently (no paired sides).
// The occluders are a height field (no thickness): gaps under floating objects count as
// occluded, as in the original method.
//
// Bent normal: each half slice's cosine-weighted mean visible direction between its view
// vector and its horizon (closed forms, as GTAO), weighted by |pn|, normalised.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/ao_hbao.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <array>
#include <numbers>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "core/parallel.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::detail::HWY_NAMESPACE {
namespace {

// The settings turned into what the pixel loop reads, once per call.
struct Constants {
  Falloff falloff;  // HBAO eq. 4's attenuation W(r) of a tap at distance r
  ScreenToView screen_to_view;
  int width, height;
  int directions, steps;
  float radius_world, max_radius_px, depth_bias_relative;
  StratifiedNoise noise;  // of the seed: a pixel's direction rotation and step jitter
  bool multibounce;
  // Direction angles i 2 pi / directions as (cos, sin), rotated per pixel by one angle.
  std::vector<std::array<float, 2>> dir_rot;

  Constants(const AoInputs& in, const AoSettings& s)
      : falloff(s.radius_world, s.falloff_fraction),
        screen_to_view(in.camera),
        width(in.depth_view.cols),
        height(in.depth_view.rows),
        directions(s.directions),
        steps(s.steps),
        radius_world(s.radius_world),
        max_radius_px(s.max_radius_px),
        depth_bias_relative(s.depth_bias_relative),
        noise(s.seed),
        multibounce(s.multibounce && in.albedo != nullptr && !in.albedo->empty()),
        dir_rot(static_cast<size_t>(s.directions)) {
    for (int i = 0; i < directions; ++i) {
      // The float pi widened to double (the direction angles' bits depend on it).
      const double a = double(i) * 2.0 * double(std::numbers::pi_v<float>) / double(directions);
      dir_rot[size_t(i)] = {float(std::cos(a)), float(std::sin(a))};
    }
  }
};

// The pixel being shaded: its position, biased origin, normal and view vector, its
// projected radius and its step jitter.
struct ShadedPixel {
  int x, y;
  glm::vec3 origin, normal, view;
  float radius_px;
  float step_noise;
};

// A direction's half slice (top of this file): its frame, the projected normal's angle n
// (cos n, sin n) and the measure m(n + pi/2) of the whole half slice, up to the tangent.
struct HalfSlice {
  Slice slice;
  float cos_n, sin_n;
  float m_tangent;
};

inline HalfSlice half_slice(const Constants& k, const ShadedPixel& px, glm::vec2 d) {
  const Slice sl = make_slice(k.screen_to_view(d.x, d.y), px.view, px.normal);
  // sin n = sign(n) sqrt(1 - cos^2 n); the tangent angle n + pi/2 has cos = -sin n and
  // sin = cos n: no trig per direction.
  const float cos_n = sl.cos_n;
  const float sin_n = std::copysign(std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n)), sl.n);
  const float tangent = sl.n + kHalfPi;  // tangent-plane angle on this side
  return {sl, cos_n, sin_n, inner_integral(tangent, -sin_n, cos_n, cos_n, sin_n)};
}

// The horizon of a half slice as (cos, sin) from the view vector, and the occluded measure
// below it.
struct Horizon {
  float cos, sin;
  float occlusion;
};

// The horizon march along screen direction d (HBAO sec. 3): taps at `steps` jittered
// distances out to the projected radius; each tap that raises the horizon adds the measure
// it newly occludes, attenuated by its distance (HBAO eq. 4).
inline Horizon march_horizon(const Constants& k, const AoInputs& in, const ShadedPixel& px, glm::vec2 d,
                             const HalfSlice& hs) {
  Horizon h{-hs.sin_n, hs.cos_n, 0.0f};  // the tangent: nothing occluded
  float m_horizon = hs.m_tangent;
  // The slice's orthonormal frame (view, direction, axis): a tap's slice-plane coordinates
  // are two dot products.
  const glm::vec3 dir = hs.slice.direction;
  for (int j = 0; j < k.steps; ++j) {
    float t = px.step_noise + float(j) * 0.618033988749895f;  // R1 offsets per step
    t -= std::floor(t);
    const float dist_px = kMinTapDistancePx + (float(j) + t) / float(k.steps) * (px.radius_px - kMinTapDistancePx);
    const int sx = px.x + round_to_int(d.x * dist_px);
    const int sy = px.y + round_to_int(d.y * dist_px);
    if (sx == px.x && sy == px.y) continue;
    if (sx < 0 || sy < 0 || sx >= k.width || sy >= k.height) break;  // left the image
    if (!in.mask.ptr<uint8_t>(sy)[sx]) continue;  // background: no occluder
    const glm::vec3 delta = load3(in.position_view, sx, sy) - px.origin;
    // On or below the tangent plane: cannot occlude (tested in 3D: rounding to pixel
    // centres moves taps off the slice, see ao_gtao.cpp).
    if (!(glm::dot(delta, px.normal) > 0.0f)) continue;
    const float dv = glm::dot(delta, px.view), dd = glm::dot(delta, dir);
    const float len2 = dv * dv + dd * dd;
    if (!(len2 > 0.0f)) continue;
    const float inv_len = 1.0f / std::sqrt(len2);
    const float c = dv * inv_len;
    if (c <= h.cos) continue;
    h.cos = c;
    // The horizon angle h = acos(c) is in [0, pi]: sin h = |dd| / len.
    h.sin = std::min(std::abs(dd) * inv_len, 1.0f);
    const float m = inner_integral(fast_acos(c), c, h.sin, hs.cos_n, hs.sin_n);
    h.occlusion += k.falloff(glm::length(delta)) * (m_horizon - m);
    m_horizon = m;
  }
  return h;
}

// The half slice's bent normal, weighted by |pn|: the cosine-weighted mean visible
// direction over [0, horizon] (closed forms, see bent_a and bent_b).
inline glm::vec3 half_slice_bent_normal(const Horizon& h, const HalfSlice& hs, const glm::vec3& view) {
  const float ch = h.cos, sh = h.sin, cos_n = hs.cos_n, sin_n = hs.sin_n;
  const float along_view = bent_a(ch, sh, cos_n, sin_n) - bent_a(1.0f, 0.0f, cos_n, sin_n);
  const float along_dir = bent_b(ch, sh, cos_n, sin_n) - bent_b(1.0f, 0.0f, cos_n, sin_n);
  return hs.slice.projected_normal_length * (along_view * view + along_dir * hs.slice.direction);
}

// AO and bent normal of pixel (x, y): 1 and none on background, 1 and the normal when the
// radius covers less than a tap.
[[gnu::always_inline]] inline void shade_pixel(const Constants& k, const AoInputs& in, int x, int y, float& ao_out,
                                              cv::Vec3f& bent_out) {
  if (!in.mask.ptr<uint8_t>(y)[x]) {
    ao_out = 1.0f;
    bent_out = cv::Vec3f(0, 0, 0);
    return;
  }
  const float depth = in.depth_view.ptr<float>(y)[x];
  const glm::vec3 p = load3(in.position_view, x, y);
  const glm::vec3 normal = load3(in.normal_view, x, y);
  const float radius_px = projected_radius_px(in.camera, depth, k.radius_world, k.max_radius_px);
  if (radius_px < 2.0f * kMinTapDistancePx) {
    ao_out = 1.0f;
    bent_out = cv::Vec3f(normal.x, normal.y, normal.z);
    return;
  }
  const int nx = x - in.frame_origin_px.x, ny = y - in.frame_origin_px.y;  // the frame's pixel
  float rotation_noise, step_noise;
  k.noise.at(nx, ny, rotation_noise, step_noise);
  const ShadedPixel px{x, y, biased_origin(p, normal, depth, k.depth_bias_relative), normal,
                       view_vector(in.camera, p), radius_px, step_noise};
  // Direction angles phi_i = (i + noise) 2 pi / directions as the fixed angles
  // i 2 pi / directions rotated by the pixel's noise angle: one sin/cos per pixel.
  const float rot = rotation_noise / float(k.directions) * (2.0f * std::numbers::pi_v<float>);
  const float rot_c = std::cos(rot), rot_s = std::sin(rot);
  float occlusion_sum = 0.0f, weight_sum = 0.0f;
  glm::vec3 bent(0.0f);
  for (int i = 0; i < k.directions; ++i) {
    const std::array<float, 2>& r = k.dir_rot[size_t(i)];
    const float cos_phi = rot_c * r[0] - rot_s * r[1];
    const float sin_phi = rot_s * r[0] + rot_c * r[1];
    const glm::vec2 d(cos_phi, -sin_phi);  // screen px, y down
    const HalfSlice hs = half_slice(k, px, d);
    const Horizon h = march_horizon(k, in, px, d, hs);
    const float pn_len = hs.slice.projected_normal_length;
    occlusion_sum += pn_len * h.occlusion;
    weight_sum += pn_len * hs.m_tangent;
    bent += half_slice_bent_normal(h, hs, px.view);
  }
  float ao = weight_sum > 0.0f ? 1.0f - occlusion_sum / weight_sum : 1.0f;
  ao = std::clamp(ao, 0.0f, 1.0f);
  if (k.multibounce) ao = multibounce(ao, albedo_luminance(in.albedo->ptr<cv::Vec3f>(y)[x]));
  ao_out = std::min(ao, 1.0f);
  const float bent_len = glm::length(bent);
  const glm::vec3 bn = bent_len > 1e-12f ? bent / bent_len : normal;
  bent_out = cv::Vec3f(bn.x, bn.y, bn.z);
}

}  // namespace

void ao_hbao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
             int nthreads) {
  const Constants k(in, s);
  parallel_rows(cv::Range(roi.y, roi.y + roi.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* ao_row = out.ao.ptr<float>(y);
      cv::Vec3f* bent_row = out.bent_normal_view.ptr<cv::Vec3f>(y);
      for (int x = roi.x; x < roi.x + roi.width; ++x) shade_pixel(k, in, x, y, ao_row[x], bent_row[x]);
    }
  });
}

}  // namespace ssdo::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::detail {

SSDO_AO_METHOD_DISPATCH(ao_hbao)

}  // namespace ssdo::detail
#endif  // HWY_ONCE
