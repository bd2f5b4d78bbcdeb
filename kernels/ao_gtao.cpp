// Ground-truth based AO (GTAO): Jimenez, Wu, Pesce, Jarabo 2016, "Practical Real-Time
// Strategies for Accurate Indirect Occlusion" (cited as "GTAO"), in the formulation of
// Intel's XeGTAO (Strugar & McCalla 2021).
//
// Per pixel, `directions` slices: planes through the eye that contain the screen line
// through the pixel at angle phi (rotated per pixel). In each slice, taps at `steps`
// distances per side along the screen line (biased towards the centre) find the visible
// occluders; the cosine-weighted visible part of the slice is integrated analytically
// with the projected-normal weighting (GTAO eq. 7 and 10's inner integral, Alg. 1):
//   a(h1, h2, n) = |pn| * sum_side (cos n + 2 h sin n - cos(2 h - n)) / 4
// where n is the angle between the projected normal pn and the view vector and h the
// signed horizon angle from the view vector.
//
// Two occluder models:
// - thickness_world = inf (height field, the paper's model): per side, the horizon is the
//   tap direction closest to the view vector; everything beyond it counts as occluded.
//   The tap weight is the distance falloff (GTAO sec. 4.3, "Bounding the sampling area";
//   XeGTAO's lerp towards the lowest horizon).
// - finite thickness_world: every tap is an occluder segment from the visible surface
//   point back along its view ray by thickness_world, clipped to the radius sphere
//   (exactly Cycles' binary "hit within radius"). The segments' angular intervals are
//   accumulated in a 64-sector visibility mask per slice (the idea of Therrien, Levesque
//   & Gilet 2023, "Screen Space Indirect Lighting with Visibility Bitmask"), with the
//   sectors equally spaced in the cosine-weighted measure above, so the visible fraction
//   of a slice is exactly popcount(free sectors) / 64 of its analytic integral. This lets
//   light through the gap under a floating object, which a height field cannot.
//
// The per-pixel estimate is the ratio sum_slices a(visible) / sum_slices a(unoccluded):
// both sums share the same slice angles, so an open surface gives exactly 1 at any
// orientation and slice count (the plain mean of a(visible) is 1 only on average over
// slice angles), and the estimator is consistent as slices grow.
//
// Bent normal: the cosine-weighted mean visible direction of each slice between its
// height-field horizons (closed-form integrals of cos(t - n)|sin t| (cos t, sin t)),
// summed over slices and normalised.
#include <bit>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "kernels/parallel.h"

namespace ssdo::detail {
namespace {

constexpr int kSectors = 64;

// Sets the sectors whose centres lie in [u0, u1] (fractions of the slice measure).
inline uint64_t sector_bits(float u0, float u1) {
  const int k0 = std::max(0, int(std::ceil(u0 * kSectors - 0.5f)));
  const int k1 = std::min(kSectors - 1, int(std::floor(u1 * kSectors - 0.5f)));
  if (k1 < k0) return 0;
  const int count = k1 - k0 + 1;
  const uint64_t run = count >= 64 ? ~uint64_t(0) : ((uint64_t(1) << count) - 1);
  return run << k0;
}

struct Constants {
  int slices;
  int steps;
  float radius_world;
  float max_radius_px;
  float thickness_world;
  bool height_field;
  float depth_bias_relative;
  uint32_t seed;
  bool multibounce;
};

}  // namespace

void ao_gtao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
             int nthreads) {
  const Camera& camera = in.camera;
  const Constants k{s.directions,
                    s.steps,
                    s.radius_world,
                    s.max_radius_px,
                    s.thickness_world,
                    !std::isfinite(s.thickness_world),
                    s.depth_bias_relative,
                    s.seed,
                    s.multibounce && in.albedo != nullptr && !in.albedo->empty()};
  const Falloff falloff(s.radius_world, s.falloff_fraction);
  const ScreenToView screen_to_view(camera);
  const int width = in.depth_view.cols, height = in.depth_view.rows;
  const bool perspective = camera.is_perspective();

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
        const float radius_px = projected_radius_px(camera, depth, k.radius_world, k.max_radius_px);
        if (radius_px < 2.0f * kMinTapDistancePx) {
          // The whole occlusion sphere fits in the pixel's neighbour: no tap can see it.
          ao_row[x] = 1.0f;
          bent_row[x] = cv::Vec3f(normal.x, normal.y, normal.z);
          continue;
        }
        const glm::vec3 origin = biased_origin(p, normal, depth, k.depth_bias_relative);
        const float slice_noise = noise01(x, y, 0, k.seed);
        const float step_noise = noise01(x, y, 1, k.seed);

        float visible_sum = 0.0f, open_sum = 0.0f;
        glm::vec3 bent(0.0f);
        for (int i = 0; i < k.slices; ++i) {
          // GTAO Alg. 1 lines 5-6: slice angle in [0, pi), rotated per pixel.
          const float phi = (float(i) + slice_noise) / float(k.slices) * kPi;
          const float dx = std::cos(phi), dy = -std::sin(phi);  // screen px, y down
          const Slice sl = make_slice(screen_to_view(dx, dy), view, normal);
          const float cos_n = sl.cos_n, sin_n = std::sin(sl.n);
          // Lowest horizons: the tangent plane on each side (n +- pi/2 from the view).
          const float low_cos_pos = std::cos(sl.n + kHalfPi);
          const float low_cos_neg = std::cos(sl.n - kHalfPi);
          float horizon_cos_pos = low_cos_pos, horizon_cos_neg = low_cos_neg;
          // Slice measure on each side and in total (inner integral at n +- pi/2).
          const float weight_neg = inner_integral(sl.n - kHalfPi, cos_n, sin_n);
          const float weight_total = cos_n + sl.n * sin_n;
          const float inv_total = weight_total > 0.0f ? 1.0f / weight_total : 0.0f;
          const float lim_pos = sl.n + kHalfPi, lim_neg = kHalfPi - sl.n;
          const float cos_lim_pos = low_cos_pos, cos_lim_neg = std::cos(lim_neg);
          uint64_t occupied = 0;

          for (int j = 0; j < k.steps; ++j) {
            // R1 sequence per step (Roberts 2018) on top of the pixel's noise.
            float t = step_noise + float(i + j * k.slices) * 0.618033988749895f;
            t -= std::floor(t);
            t = (float(j) + t) / float(k.steps);
            // Distribution power 2: denser near the centre, where occluders matter most
            // for the cosine weight (XeGTAO's SampleDistributionPower default).
            const float dist_px = kMinTapDistancePx + t * t * (radius_px - kMinTapDistancePx);
            const int ox = int(std::lround(dx * dist_px)), oy = int(std::lround(dy * dist_px));
            if (ox == 0 && oy == 0) continue;
            for (int side = 0; side < 2; ++side) {
              const int sx = side == 0 ? x + ox : x - ox;
              const int sy = side == 0 ? y + oy : y - oy;
              if (sx < 0 || sy < 0 || sx >= width || sy >= height) continue;
              if (!in.mask.ptr<uint8_t>(sy)[sx]) continue;  // background: no occluder
              const glm::vec3 tap = load3(in.position_view, sx, sy);
              const glm::vec3 delta = tap - origin;
              // A tap on or below the tangent plane cannot occlude the hemisphere (nor can
              // the rest of its segment, which runs away from the eye, i.e. further down).
              // Testing in 3D first matters: rounding taps to pixel centres moves them off
              // the slice, and their slice angle alone would put tilted planes above
              // their own tangent line.
              if (!(glm::dot(delta, normal) > 0.0f)) continue;
              const float dist = glm::length(delta);
              // The tap's angle in the slice: of its projection onto the slice plane.
              const glm::vec3 delta_slice = delta - sl.axis * glm::dot(delta, sl.axis);
              const float dist_slice = glm::length(delta_slice);
              if (!(dist_slice > 0.0f)) continue;
              const float tap_cos = glm::dot(delta_slice, view) / dist_slice;
              // Height-field horizon (also the bent normal's horizon in the mask model).
              const float w = falloff(dist);
              float& horizon_cos = side == 0 ? horizon_cos_pos : horizon_cos_neg;
              const float low_cos = side == 0 ? low_cos_pos : low_cos_neg;
              horizon_cos = std::max(horizon_cos, low_cos + (tap_cos - low_cos) * w);
              if (k.height_field) continue;

              // Occluder segment tap + t r, t in [0, thickness], r = the tap's view ray
              // direction (away from the eye), clipped to |delta + t r| <= radius.
              const glm::vec3 ray = perspective ? glm::normalize(tap) : glm::vec3(0, 0, -1);
              const float b = glm::dot(delta, ray);
              const float c = dist * dist - k.radius_world * k.radius_world;
              const float disc = b * b - c;
              if (disc < 0.0f) continue;
              const float root = std::sqrt(disc);
              const float t0 = std::max(0.0f, -b - root);
              const float t1 = std::min(k.thickness_world, -b + root);
              if (t1 < t0) continue;
              // Angles (unsigned, from the view vector) of the segment's two ends.
              glm::vec3 e0 = delta + t0 * ray, e1 = delta + t1 * ray;
              e0 -= sl.axis * glm::dot(e0, sl.axis);
              e1 -= sl.axis * glm::dot(e1, sl.axis);
              const float c0 = std::clamp(glm::dot(e0, view) / glm::length(e0), -1.0f, 1.0f);
              const float c1 = std::clamp(glm::dot(e1, view) / glm::length(e1), -1.0f, 1.0f);
              // Unsigned angles a = acos(c) of the two ends, ordered, clipped to the
              // hemisphere's limit on this side (n + pi/2 on +, pi/2 - n on -).
              float ca = std::max(c0, c1), cb = std::min(c0, c1);  // a(ca) <= a(cb)
              const float lim = side == 0 ? lim_pos : lim_neg;
              const float cos_lim = side == 0 ? cos_lim_pos : cos_lim_neg;
              if (ca <= cos_lim) continue;  // the whole segment is below the tangent plane
              cb = std::max(cb, cos_lim);
              const float aa = std::min(fast_acos(ca), lim), ab = std::min(fast_acos(cb), lim);
              const float sa = std::sqrt(std::max(0.0f, 1.0f - ca * ca));
              const float sb = std::sqrt(std::max(0.0f, 1.0f - cb * cb));
              float u0, u1;
              if (side == 0) {
                u0 = weight_neg + inner_integral(aa, ca, sa, cos_n, sin_n);
                u1 = weight_neg + inner_integral(ab, cb, sb, cos_n, sin_n);
              } else {
                // Signed angle -a: the weight of [-a, 0] comes off the negative side.
                u0 = weight_neg - inner_integral(-ab, cb, -sb, cos_n, sin_n);
                u1 = weight_neg - inner_integral(-aa, ca, -sa, cos_n, sin_n);
              }
              occupied |= sector_bits(u0 * inv_total, u1 * inv_total);
            }
          }

          const float pn_len = sl.projected_normal_length;
          // Horizon angles (GTAO Alg. 1 line 27): positive side +acos, negative -acos.
          const float h_pos = fast_acos(horizon_cos_pos);
          const float h_neg = -fast_acos(horizon_cos_neg);
          float visible;
          if (k.height_field) {
            visible = inner_integral(h_pos, cos_n, sin_n) + inner_integral(h_neg, cos_n, sin_n);
          } else {
            const int free_sectors = kSectors - std::popcount(occupied);
            visible = weight_total * float(free_sectors) * (1.0f / kSectors);
          }
          visible_sum += pn_len * visible;
          open_sum += pn_len * weight_total;

          const float cp = std::cos(h_pos), sp = std::sin(h_pos);
          const float cm = std::cos(h_neg), sm = std::sin(h_neg);
          const float a0 = bent_a(1.0f, 0.0f, cos_n, sin_n), b0 = bent_b(1.0f, 0.0f, cos_n, sin_n);
          const float along_view = bent_a(cp, sp, cos_n, sin_n) + bent_a(cm, sm, cos_n, sin_n) - 2.0f * a0;
          const float along_dir = bent_b(cp, sp, cos_n, sin_n) + bent_b(cm, sm, cos_n, sin_n) - 2.0f * b0;
          bent += pn_len * (along_view * view + along_dir * sl.direction);
        }

        float ao = open_sum > 0.0f ? std::clamp(visible_sum / open_sum, 0.0f, 1.0f) : 1.0f;
        if (k.multibounce) ao = multibounce(ao, albedo_luminance(in.albedo->ptr<cv::Vec3f>(y)[x]));
        ao_row[x] = std::min(ao, 1.0f);
        const float bent_len = glm::length(bent);
        const glm::vec3 bn = bent_len > 1e-12f ? bent / bent_len : normal;
        bent_row[x] = cv::Vec3f(bn.x, bn.y, bn.z);
      }
    }
  });
}

}  // namespace ssdo::detail
