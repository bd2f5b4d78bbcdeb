// Confidence: the observed fraction of the sampled neighbourhood (definition in
// confidence.h).
//
// Rays are parametrised by planar depth s: x(s) = o + s u with u.z = -1 (perspective: o = 0
// and u = the view-space point of the pixel at depth 1; orthographic: o = the point at depth
// 0, u = (0, 0, -1)). Both are affine in the continuous pixel position (view_from_pixel_depth
// solves a linear system at fixed depth), so one pixel's ray costs two multiply-adds. In s,
// the sphere |x(s) - p| = R is the quadratic (u.u) s^2 + 2 (u.f) s + (f.f - R^2) = 0 with
// f = o - p, the tangent plane n.(x(s) - p) = 0 is s* = -(n.f) / (n.u), and the stored
// surface at the tap is s = depth_view(tap). Lengths in s scale to lengths along the ray by
// |u|, which weights each chord by its true length.
#include "kernels/confidence.h"

#include "kernels/settings_check.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "kernels/half_resolution.h"
#include "kernels/noise.h"
#include "kernels/parallel.h"

namespace ssdo {
namespace {

// Golden angle, radians: successive Vogel-spiral taps (Vogel 1979, "A better way to
// construct the sunflower head") turn by it, which spreads N taps evenly over a disk for
// any N.
constexpr float kGoldenAngle = 2.39996322972865332f;

// ConfidenceSettings::taps' upper bound: a pixel's taps fit in fixed arrays.
constexpr int kMaxTaps = 256;

struct RayMap {
  glm::vec3 o0, ox, oy;  // o(px, py) = o0 + px ox + py oy
  glm::vec3 u0, ux, uy;  // u(px, py) = u0 + px ux + py uy
};

RayMap make_ray_map(const Camera& cam) {
  RayMap m;
  auto point = [&](float px, float py, float depth) {
    return cam.view_from_pixel_depth(glm::vec2(px, py), depth);
  };
  if (cam.is_perspective()) {
    m.o0 = m.ox = m.oy = glm::vec3(0.0f);
    m.u0 = point(0.0f, 0.0f, 1.0f);
    m.ux = point(1.0f, 0.0f, 1.0f) - m.u0;
    m.uy = point(0.0f, 1.0f, 1.0f) - m.u0;
  } else {
    m.o0 = point(0.0f, 0.0f, 0.0f);
    m.ox = point(1.0f, 0.0f, 0.0f) - m.o0;
    m.oy = point(0.0f, 1.0f, 0.0f) - m.o0;
    m.u0 = glm::vec3(0.0f, 0.0f, -1.0f);
    m.ux = m.uy = glm::vec3(0.0f);
  }
  return m;
}

}  // namespace

std::string validate(const ConfidenceSettings& s) {
  if (std::string e = detail::check_radius(s.radius_world, s.max_radius_px); !e.empty()) return e;
  if (s.taps < 4 || s.taps > kMaxTaps) return detail::out_of_range("taps", s.taps, "[4, 256]");
  if (!(s.depth_bias_relative >= 0.0f && s.depth_bias_relative <= 0.1f))
    return detail::out_of_range("depth_bias_relative", s.depth_bias_relative, "[0, 0.1]");
  if (s.resolution_divisor < 1 || s.resolution_divisor > 2)
    return detail::out_of_range("resolution_divisor", s.resolution_divisor, "[1, 2]");
  return {};
}

void compute_confidence(const cv::Mat& depth_view, const cv::Mat& normal_view,
                        const cv::Mat& mask, const Camera& camera,
                        const ConfidenceSettings& s, cv::Mat& confidence, cv::Rect roi,
                        int nthreads, const HalfGrid* half_grid) {
  CV_Assert(validate(s).empty());
  CV_Assert(depth_view.type() == CV_32FC1);
  const cv::Size size = depth_view.size();
  CV_Assert(normal_view.type() == CV_32FC3 && normal_view.size() == size);
  CV_Assert(mask.type() == CV_8UC1 && mask.size() == size);
  CV_Assert(camera.width_px == size.width && camera.height_px == size.height);
  if (confidence.size() != size || confidence.type() != CV_32FC1)
    confidence.create(size, CV_32FC1);
  const cv::Rect r = resolve_roi(roi, size);
  if (r.empty()) return;
  if (s.resolution_divisor == 2) {
    const cv::Mat no_positions;
    const FullGrid full{depth_view, normal_view, no_positions, mask, camera};
    HalfGrid own;
    const HalfGrid& h = shared_or_own_half_grid(full, half_grid, own, false, nthreads);
    ConfidenceSettings half_settings = s;
    half_settings.resolution_divisor = 1;
    cv::Mat half_confidence;
    compute_confidence(h.depth_view, h.normal_view, h.mask, h.camera, half_settings, half_confidence,
                       half_grid_roi(r, size), nthreads);
    // Background and pixels with no foreground texel near: 1, as on background.
    const UpsampleImage images[] = {{half_confidence, confidence, cv::Scalar(1.0), cv::Scalar(1.0)}};
    upsample_from_half_grid(full, h, images, r, nthreads);
    return;
  }
  const RayMap rays = make_ray_map(camera);
  const int width = size.width, height = size.height;
  const int n_taps = s.taps;
  const float bias_scale = 1.0f + s.depth_bias_relative;
  // The unrotated Vogel spiral: equal-area rings (rho = sqrt((k + 0.5) / N)), golden-angle
  // turns. Each pixel rotates it by its own angle (a 2x2 rotation per tap, not a sincos).
  std::vector<float> spiral_x(static_cast<size_t>(n_taps)), spiral_y(static_cast<size_t>(n_taps));
  for (int k = 0; k < n_taps; ++k) {
    const float rho = std::sqrt((float(k) + 0.5f) / float(n_taps));
    const float angle = float(k) * kGoldenAngle;
    spiral_x[size_t(k)] = rho * std::cos(angle);
    spiral_y[size_t(k)] = rho * std::sin(angle);
  }

  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    struct Taps {  // one pixel's taps, structure of arrays
      alignas(32) float x[kMaxTaps], y[kMaxTaps], s0[kMaxTaps], s1[kMaxTaps], len_scale[kMaxTaps];
    } tap;
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = mask.ptr<uint8_t>(y);
      const float* depth_row = depth_view.ptr<float>(y);
      const cv::Vec3f* normal_row = normal_view.ptr<cv::Vec3f>(y);
      float* out = confidence.ptr<float>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        const float d = depth_row[x];
        if (mask_row[x] == 0 || !(d > 0.0f) || !std::isfinite(d)) {
          out[x] = 1.0f;
          continue;
        }
        const float pxc = float(x) + 0.5f, pyc = float(y) + 0.5f;
        const glm::vec3 p = rays.o0 + pxc * rays.ox + pyc * rays.oy +
                            d * (rays.u0 + pxc * rays.ux + pyc * rays.uy);
        const glm::vec3 n(normal_row[x][0], normal_row[x][1], normal_row[x][2]);
        // The estimator's neighbourhood: the radius, shrunk where its projection exceeds
        // max_radius_px (the methods shrink theirs the same way).
        const glm::vec2 ppu = camera.pixels_per_unit(d);
        float radius = s.radius_world;
        const float radius_px_max = radius * std::max(ppu.x, ppu.y);
        if (radius_px_max > s.max_radius_px) radius *= s.max_radius_px / radius_px_max;
        const float rx_px = radius * ppu.x, ry_px = radius * ppu.y;
        const float r2 = radius * radius;
        const float rotation = 6.2831853f * noise01(x, y, 0, s.seed);
        const float cos_r = std::cos(rotation), sin_r = std::sin(rotation);
        // Phase 1, every tap at once (no branch, so the compiler runs 8 taps per
        // instruction): the tap pixel, and the chord [s0, s1] of the hemisphere along the
        // ray through its centre (where its depth was sampled), in ray parameter units;
        // len_scale converts them to lengths. Taps whose ray misses get s1 <= s0.
        for (int k = 0; k < n_taps; ++k) {
          const float vx = spiral_x[size_t(k)], vy = spiral_y[size_t(k)];
          const float tx = std::floor(pxc + rx_px * (cos_r * vx - sin_r * vy));
          const float ty = std::floor(pyc + ry_px * (sin_r * vx + cos_r * vy));
          const float cx = tx + 0.5f, cy = ty + 0.5f;
          const glm::vec3 o = rays.o0 + cx * rays.ox + cy * rays.oy;
          const glm::vec3 u = rays.u0 + cx * rays.ux + cy * rays.uy;
          const glm::vec3 f = o - p;
          const float a = glm::dot(u, u), b = glm::dot(u, f), c = glm::dot(f, f) - r2;
          const float disc = b * b - a * c;
          const float root = std::sqrt(std::max(disc, 0.0f));
          float s0 = std::max((-b - root) / a, 0.0f), s1 = (-b + root) / a;
          // Clip to the hemisphere n.(x - p) >= 0. A ray parallel to the tangent plane
          // (nu = 0) is kept whole above it and dropped below it.
          const float nu = glm::dot(n, u), nf = glm::dot(n, f);
          const float s_plane = -nf / nu;
          s1 = nu < 0.0f ? std::min(s1, s_plane) : s1;
          s0 = nu > 0.0f ? std::max(s0, s_plane) : s0;
          const bool hit = disc > 0.0f && !(nu == 0.0f && nf < 0.0f) && s1 > s0;
          tap.x[k] = tx;
          tap.y[k] = ty;
          tap.s0[k] = s0;
          tap.s1[k] = hit ? s1 : s0;  // an empty chord: weighs nothing below
          tap.len_scale[k] = std::sqrt(a);
        }
        // Phase 2, in tap order: the sums, and the depth reads (gathers).
        double observed = 0.0, total = 0.0;
        for (int k = 0; k < n_taps; ++k) {
          const float s0 = tap.s0[k], s1 = tap.s1[k];
          if (!(s1 > s0)) continue;
          const float len_scale = tap.len_scale[k];
          total += double((s1 - s0) * len_scale);
          const int tx = int(tap.x[k]), ty = int(tap.y[k]);
          if (tx < 0 || ty < 0 || tx >= width || ty >= height) continue;  // off screen
          if (mask.ptr<uint8_t>(ty)[tx] == 0) continue;                     // unknown
          const float d_tap = depth_view.ptr<float>(ty)[tx];
          if (!(d_tap > 0.0f) || !std::isfinite(d_tap)) continue;
          // In front of the stored surface (within the relative bias: the pixel's own
          // plane seen at the tap is observed).
          const float s_surface = d_tap * bias_scale;
          const float seen = std::min(s1, s_surface) - s0;
          if (seen > 0.0f) observed += double(seen * len_scale);
        }
        out[x] = total > 0.0 ? float(std::clamp(observed / total, 0.0, 1.0)) : 1.0f;
      }
    }
  });
}

}  // namespace ssdo
