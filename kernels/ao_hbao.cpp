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
#include <array>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "core/parallel.h"

namespace ssdo::detail {

void ao_hbao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
             int nthreads) {
  const Camera& camera = in.camera;
  const Falloff falloff(s.radius_world, s.falloff_fraction);
  const ScreenToView screen_to_view(camera);
  const int width = in.depth_view.cols, height = in.depth_view.rows;
  const int directions = s.directions, steps = s.steps;
  const bool use_multibounce = s.multibounce && in.albedo != nullptr && !in.albedo->empty();
  // Direction angles i 2 pi / directions as (cos, sin), rotated per pixel by one angle.
  std::vector<std::array<float, 2>> dir_rot(static_cast<size_t>(directions));
  for (int i = 0; i < directions; ++i) {
    const double a = double(i) * 2.0 * double(kPi) / double(directions);
    dir_rot[size_t(i)] = {float(std::cos(a)), float(std::sin(a))};
  }

  parallel_rows(cv::Range(roi.y, roi.y + roi.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      float* ao_row = out.ao.ptr<float>(y);
      cv::Vec3f* bent_row = out.bent_normal_view.ptr<cv::Vec3f>(y);
      for (int x = roi.x; x < roi.x + roi.width; ++x) {
        if (!mask_row[x]) {
          ao_row[x] = 1.0f;
          bent_row[x] = cv::Vec3f(0, 0, 0);
          continue;
        }
        const float depth = depth_row[x];
        const glm::vec3 p = load3(in.position_view, x, y);
        const glm::vec3 normal = load3(in.normal_view, x, y);
        const glm::vec3 view = view_vector(camera, p);
        const float radius_px = projected_radius_px(camera, depth, s.radius_world, s.max_radius_px);
        if (radius_px < 2.0f * kMinTapDistancePx) {
          ao_row[x] = 1.0f;
          bent_row[x] = cv::Vec3f(normal.x, normal.y, normal.z);
          continue;
        }
        const glm::vec3 origin = biased_origin(p, normal, depth, s.depth_bias_relative);
        const float angle_noise = noise01(x, y, 0, s.seed);
        const float step_noise = noise01(x, y, 1, s.seed);

        // Direction angles phi_i = (i + noise) 2 pi / directions as the fixed angles
        // i 2 pi / directions rotated by the pixel's noise angle: one sin/cos per pixel.
        const float rot = angle_noise / float(directions) * (2.0f * kPi);
        const float rot_c = std::cos(rot), rot_s = std::sin(rot);

        float occlusion_sum = 0.0f, weight_sum = 0.0f;
        glm::vec3 bent(0.0f);
        for (int i = 0; i < directions; ++i) {
          const float cos_phi = rot_c * dir_rot[size_t(i)][0] - rot_s * dir_rot[size_t(i)][1];
          const float sin_phi = rot_s * dir_rot[size_t(i)][0] + rot_c * dir_rot[size_t(i)][1];
          const float dx = cos_phi, dy = -sin_phi;  // screen px, y down
          const Slice sl = make_slice(screen_to_view(dx, dy), view, normal);
          // sin n = sign(n) sqrt(1 - cos^2 n); the tangent angle n + pi/2 has cos = -sin n
          // and sin = cos n: no trig per direction.
          const float cos_n = sl.cos_n;
          const float sin_n = std::copysign(std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n)), sl.n);
          const float tangent = sl.n + kHalfPi;  // tangent-plane angle on this side
          const float m_tangent = inner_integral(tangent, -sin_n, cos_n, cos_n, sin_n);
          float horizon_cos = -sin_n;
          float horizon_sin = cos_n;
          float m_horizon = m_tangent;
          float occlusion = 0.0f;
          // The slice's orthonormal frame (view, direction, axis): a tap's slice-plane
          // coordinates are two dot products.
          const glm::vec3 dir = sl.direction;
          for (int j = 0; j < steps; ++j) {
            float t = step_noise + float(j) * 0.618033988749895f;  // R1 offsets per step
            t -= std::floor(t);
            const float dist_px = kMinTapDistancePx + (float(j) + t) / float(steps) * (radius_px - kMinTapDistancePx);
            const int sx = x + round_to_int(dx * dist_px);
            const int sy = y + round_to_int(dy * dist_px);
            if (sx == x && sy == y) continue;
            if (sx < 0 || sy < 0 || sx >= width || sy >= height) break;  // left the image
            if (!in.mask.ptr<uint8_t>(sy)[sx]) continue;  // background: no occluder
            const glm::vec3 delta = load3(in.position_view, sx, sy) - origin;
            // On or below the tangent plane: cannot occlude (tested in 3D: rounding to
            // pixel centres moves taps off the slice, see ao_gtao.cpp).
            if (!(glm::dot(delta, normal) > 0.0f)) continue;
            const float dv = glm::dot(delta, view), dd = glm::dot(delta, dir);
            const float len2 = dv * dv + dd * dd;
            if (!(len2 > 0.0f)) continue;
            const float inv_len = 1.0f / std::sqrt(len2);
            const float c = dv * inv_len;
            if (c <= horizon_cos) continue;
            horizon_cos = c;
            // The horizon angle h = acos(c) is in [0, pi]: sin h = |dd| / len.
            horizon_sin = std::min(std::abs(dd) * inv_len, 1.0f);
            const float h = fast_acos(c);
            const float m = inner_integral(h, c, horizon_sin, cos_n, sin_n);
            occlusion += falloff(glm::length(delta)) * (m_horizon - m);
            m_horizon = m;
          }
          const float pn_len = sl.projected_normal_length;
          occlusion_sum += pn_len * occlusion;
          weight_sum += pn_len * m_tangent;
          // Bent normal over the visible part [0, horizon] of this half slice.
          const float ch = horizon_cos, sh = horizon_sin;
          const float along_view = bent_a(ch, sh, cos_n, sin_n) - bent_a(1.0f, 0.0f, cos_n, sin_n);
          const float along_dir = bent_b(ch, sh, cos_n, sin_n) - bent_b(1.0f, 0.0f, cos_n, sin_n);
          bent += pn_len * (along_view * view + along_dir * sl.direction);
        }
        float ao = weight_sum > 0.0f ? 1.0f - occlusion_sum / weight_sum : 1.0f;
        ao = std::clamp(ao, 0.0f, 1.0f);
        if (use_multibounce) ao = multibounce(ao, albedo_luminance(in.albedo->ptr<cv::Vec3f>(y)[x]));
        ao_row[x] = std::min(ao, 1.0f);
        const float bent_len = glm::length(bent);
        const glm::vec3 bn = bent_len > 1e-12f ? bent / bent_len : normal;
        bent_row[x] = cv::Vec3f(bn.x, bn.y, bn.z);
      }
    }
  });
}

}  // namespace ssdo::detail
