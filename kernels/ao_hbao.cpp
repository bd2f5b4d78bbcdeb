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
// measure of the occluded elevations (HBAO eq. 3). Under the cosine weight around the
// normal, the measure of elevations [0, h] at one azimuth is
//   int_0^h sin(e) cos(e) de / int_0^{pi/2} sin(e) cos(e) de = sin^2(h),
// so the term becomes sin^2(h) - sin^2(t) with t = 0, accumulated per tap with the
// distance falloff as in HBAO's attenuated form (HBAO eq. 4 with W(r) = falloff(r)):
//   occlusion(dir) = sum_i W(r_i) (sin^2 h_i - sin^2 h_{i-1}) over taps raising the horizon.
// The directions are uniform in screen angle phi, but the integral runs over the tangent-
// plane azimuth psi of each direction. With gamma the angle between normal and view and
// phi measured from the projected normal's direction in the image plane,
// tan(psi) = cos(gamma) tan(phi), so each direction is weighted by
//   J = d psi / d phi = cos(gamma) / (cos^2(phi) + cos^2(gamma) sin^2(phi))
// and AO = 1 - sum J occlusion / sum J (a ratio estimator: open surfaces give exactly 1).
// The occluders are a height field (no thickness): gaps under floating objects count as
// occluded, as in the original method.
//
// Bent normal: the J-weighted mean of each direction's unoccluded mid direction (halfway
// in elevation between its horizon and the normal), normalised.
#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "kernels/parallel.h"

namespace ssdo::detail {

void ao_hbao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
             int nthreads) {
  const Camera& camera = in.camera;
  const Falloff falloff(s.radius_world, s.falloff_fraction);
  const ScreenToView screen_to_view(camera);
  const int width = in.depth_view.cols, height = in.depth_view.rows;
  const int directions = s.directions, steps = s.steps;
  const bool use_multibounce = s.multibounce && in.albedo != nullptr && !in.albedo->empty();

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
        // Tilt of the tangent plane seen from the eye: cos(gamma) and the image-plane
        // direction of the projected normal (phi is measured from it).
        const float cos_gamma = std::clamp(glm::dot(normal, view), 0.0f, 1.0f);
        // Back-facing normals (dot < 0) cannot be seen; clamp keeps J finite. A floor of
        // 1e-3 (grazing beyond 89.9 deg) bounds J's peak at 1e3, far above any weight ratio
        // that changes a result, without an infinity.
        const float cg = std::max(cos_gamma, 1e-3f);
        const glm::vec3 tilt = normal - glm::dot(normal, view) * view;
        const float tilt_len = glm::length(tilt);
        const glm::vec3 tilt_dir = tilt_len > 1e-6f ? tilt / tilt_len : glm::vec3(0.0f);
        const float angle_noise = noise01(x, y, 0, s.seed);
        const float step_noise = noise01(x, y, 1, s.seed);

        float occlusion_sum = 0.0f, weight_sum = 0.0f;
        glm::vec3 bent(0.0f);
        for (int i = 0; i < directions; ++i) {
          const float phi = (float(i) + angle_noise) / float(directions) * (2.0f * kPi);
          const float dx = std::cos(phi), dy = -std::sin(phi);  // screen px, y down
          glm::vec3 dir_view = screen_to_view(dx, dy);
          dir_view = glm::normalize(dir_view - glm::dot(dir_view, view) * view);
          const float cos_phi = glm::dot(dir_view, tilt_dir);  // 0 when facing the eye
          const float sin2_phi = 1.0f - cos_phi * cos_phi;
          const float jacobian = cg / (cos_phi * cos_phi + cg * cg * sin2_phi);

          float sin2_horizon = 0.0f;  // the tangent plane: sin^2(t) = 0
          float occlusion = 0.0f;
          for (int j = 0; j < steps; ++j) {
            float t = step_noise + float(j) * 0.618033988749895f;  // R1 offsets per step
            t -= std::floor(t);
            const float dist_px = kMinTapDistancePx + (float(j) + t) / float(steps) * (radius_px - kMinTapDistancePx);
            const int sx = x + int(std::lround(dx * dist_px));
            const int sy = y + int(std::lround(dy * dist_px));
            if (sx == x && sy == y) continue;
            if (sx < 0 || sy < 0 || sx >= width || sy >= height) break;  // left the image
            if (!in.mask.ptr<uint8_t>(sy)[sx]) continue;  // background: no occluder
            const glm::vec3 delta = load3(in.position_view, sx, sy) - origin;
            const float dist2 = glm::dot(delta, delta);
            if (!(dist2 > 0.0f)) continue;
            const float elevation_dot = glm::dot(delta, normal);
            if (elevation_dot <= 0.0f) continue;  // below the tangent plane
            const float sin2 = elevation_dot * elevation_dot / dist2;
            if (sin2 > sin2_horizon) {
              occlusion += falloff(std::sqrt(dist2)) * (sin2 - sin2_horizon);
              sin2_horizon = sin2;
            }
          }
          occlusion_sum += jacobian * occlusion;
          weight_sum += jacobian;
          // Unoccluded mid direction: elevation halfway between the horizon and the zenith.
          const glm::vec3 along = dir_view - glm::dot(dir_view, normal) * normal;
          const float along_len = glm::length(along);
          // A direction along the normal (edge-on surface) has no tangent azimuth.
          const glm::vec3 tangent = along_len > 1e-6f ? along / along_len : glm::vec3(0.0f);
          const float h = std::asin(std::sqrt(std::min(sin2_horizon, 1.0f)));
          const float e = 0.5f * (h + kHalfPi);
          bent += jacobian * (1.0f - occlusion) * (std::cos(e) * tangent + std::sin(e) * normal);
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
