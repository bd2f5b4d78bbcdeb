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
//   Sparse taps: a few taps per side sample a surface at a few points only, and their
//   segments alone leave the angles between them open (a wall seen through 4 taps lets
//   light through 3 gaps). Consecutive taps of a side whose depths differ by at most the
//   thickness (their segments overlap in depth: the same surface, or touching ones) are
//   taken as connected: the angles between them are occluded too (the hull of their two
//   intervals). A tap on or below the tangent plane connects at the tangent limit when
//   the next tap is within the thickness of it in 3D, so a wall rising from the floor
//   occludes down to the floor line as the height field does, and the gap under a
//   floating object stays open.
//   Taps on one plane (normals within 18 deg, each on the other's tangent plane within the
//   thickness) connect at any depth difference: a wall seen at a grazing angle changes
//   depth quickly from tap to tap but is still one surface.
//
// The per-pixel estimate is the ratio sum_slices a(visible) / sum_slices a(unoccluded):
// both sums share the same slice angles, so an open surface gives exactly 1 at any
// orientation and slice count (the plain mean of a(visible) is 1 only on average over
// slice angles), and the estimator is consistent as slices grow.
//
// Bent normal: the cosine-weighted mean visible direction of each slice between its
// height-field horizons (closed-form integrals of cos(t - n)|sin t| (cos t, sin t)),
// summed over slices and normalised.
#include <array>
#include <bit>
#include <vector>

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

// What a tap reads from the pixel it lands in, packed in 16 bytes (one load): the view-space
// position and the planar depth, negative on masked pixels (no occluder there).
struct Texel {
  float x, y, z, depth_view;
  float nx, ny, nz, plane_c;  // unit normal and its tangent plane dot(n, x) = plane_c
};

void build_texels(const AoInputs& in, std::vector<Texel>& texels, int nthreads) {
  const int width = in.depth_view.cols;
  texels.resize(size_t(width) * size_t(in.depth_view.rows));  // before the parallel loop
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      const cv::Vec3f* pos_row = in.position_view.ptr<cv::Vec3f>(y);
      const cv::Vec3f* nor_row = in.normal_view.ptr<cv::Vec3f>(y);
      Texel* out = texels.data() + size_t(y) * size_t(width);
      for (int x = 0; x < width; ++x) {
        const cv::Vec3f& p = pos_row[x];
        const cv::Vec3f& n = nor_row[x];
        out[x] = mask_row[x] ? Texel{p[0], p[1], p[2], depth_row[x], n[0], n[1], n[2], n.dot(p)}
                             : Texel{0.0f, 0.0f, 0.0f, -1.0f, 0.0f, 0.0f, 0.0f, 0.0f};
      }
    }
  });
}

// Normals within acos(0.95) = 18 deg of each other: the same plane up to the curvature
// between two taps (a cylinder of radius 1 turns by 18 deg over 0.3 units) or the rounding
// of reconstructed normals; creases of a box (90 deg) and floor-vs-underside (180 deg) are
// never connected this way.
constexpr float kCoplanarMinCos = 0.95f;

// b lies on a's tangent plane within tol, and their normals agree: the same surface.
inline bool coplanar(const Texel& a, const Texel& b, float tol) {
  return a.nx * b.nx + a.ny * b.ny + a.nz * b.nz >= kCoplanarMinCos &&
         std::abs(a.nx * b.x + a.ny * b.y + a.nz * b.z - a.plane_c) <= tol;
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

// A side's last tap, for the connection rule (top of this file): its depth and its
// occluded interval in fractions of the slice measure (u0 > u1: no interval).
struct SideState {
  float depth_view = -1.0f;  // < 0: no previous tap to connect to
  float u0 = 1.0f, u1 = 0.0f;
  const Texel* texel = nullptr;
  bool below = false;  // the tap was on or below the tangent plane (interval at the limit)
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
  std::vector<Texel> texels;
  build_texels(in, texels, nthreads);
  // Second depth layer, when given: per-tap thickness of the visibility mask's segments.
  const cv::Mat* back = !k.height_field && in.depth_back_view != nullptr &&
                                !in.depth_back_view->empty() &&
                                in.depth_back_view->size() == in.depth_view.size()
                            ? in.depth_back_view
                            : nullptr;
  // Slice angles i pi / slices as (cos, sin), rotated per pixel by one angle: no trig per
  // slice in the pixel loop.
  std::vector<std::array<float, 2>> slice_rot(size_t(k.slices));
  for (int i = 0; i < k.slices; ++i) {
    const double a = double(i) * double(kPi) / double(k.slices);
    slice_rot[size_t(i)] = {float(std::cos(a)), float(std::sin(a))};
  }
  const float r2 = k.radius_world * k.radius_world;

  parallel_rows(cv::Range(roi.y, roi.y + roi.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      const cv::Vec3f* normal_row = in.normal_view.ptr<cv::Vec3f>(y);
      float* ao_row = out.ao.ptr<float>(y);
      cv::Vec3f* bent_row = out.bent_normal_view.ptr<cv::Vec3f>(y);
      for (int x = roi.x; x < roi.x + roi.width; ++x) {
        if (!mask_row[x]) {
          ao_row[x] = 1.0f;
          bent_row[x] = cv::Vec3f(0, 0, 0);
          continue;
        }
        const float depth = depth_row[x];
        const Texel& centre = texels[size_t(y) * size_t(width) + size_t(x)];
        const glm::vec3 p(centre.x, centre.y, centre.z);
        const glm::vec3 normal(normal_row[x][0], normal_row[x][1], normal_row[x][2]);
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
        const float rot = slice_noise / float(k.slices) * kPi;
        const float rot_c = std::cos(rot), rot_s = std::sin(rot);

        float visible_sum = 0.0f, open_sum = 0.0f;
        glm::vec3 bent(0.0f);
        for (int i = 0; i < k.slices; ++i) {
          // GTAO Alg. 1 lines 5-6: slice angle phi in [0, pi), rotated per pixel.
          const float cos_phi = rot_c * slice_rot[size_t(i)][0] - rot_s * slice_rot[size_t(i)][1];
          const float sin_phi = rot_s * slice_rot[size_t(i)][0] + rot_c * slice_rot[size_t(i)][1];
          const float dx = cos_phi, dy = -sin_phi;  // screen px, y down
          const Slice sl = make_slice(screen_to_view(dx, dy), view, normal);
          // n = sign acos(cos_n), so sin n = sign sqrt(1 - cos_n^2) and the tangent limits
          // n +- pi/2 have cos = -+sin n: no trig per slice.
          const float cos_n = sl.cos_n;
          const float sin_n = std::copysign(std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n)), sl.n);
          const float low_cos_pos = -sin_n, low_cos_neg = sin_n;
          float horizon_cos_pos = low_cos_pos, horizon_cos_neg = low_cos_neg;
          // Slice measure of the negative side and in total (inner integral at n +- pi/2).
          const float weight_neg = inner_integral(sl.n - kHalfPi, sin_n, -cos_n, cos_n, sin_n);
          const float weight_total = cos_n + sl.n * sin_n;
          const float inv_total = weight_total > 0.0f ? 1.0f / weight_total : 0.0f;
          const float lim_pos = sl.n + kHalfPi, lim_neg = kHalfPi - sl.n;
          // The slice's orthonormal frame and the origin and the orthographic view ray
          // in it (per slice, so that each tap needs three dot products).
          const glm::vec3 dir = sl.direction, axis = sl.axis;
          const float origin_v = glm::dot(origin, view), origin_d = glm::dot(origin, dir),
                      origin_a = glm::dot(origin, axis);
          const float ray_ortho_v = -view.z, ray_ortho_d = -dir.z, ray_ortho_a = -axis.z;
          uint64_t occupied = 0;
          SideState state[2];

          for (int j = 0; j < k.steps; ++j) {
            // R1 sequence per step (Roberts 2018) on top of the pixel's noise.
            float t = step_noise + float(i + j * k.slices) * 0.618033988749895f;
            t -= std::floor(t);
            t = (float(j) + t) / float(k.steps);
            // Uniform in screen distance (distribution power 1). XeGTAO's power 2 puts taps
            // near the centre; against the ray-marched reference on the shared frames
            // (cornell, greeble, depthgap) power 1 halved the error at 8 steps (MAE 0.057
            // -> 0.040 on cornell): far taps carry walls seen at grazing angles, whose
            // occlusion the dense near taps never see.
            const float dist_px = kMinTapDistancePx + t * (radius_px - kMinTapDistancePx);
            const int ox = round_to_int(dx * dist_px), oy = round_to_int(dy * dist_px);
            if (ox == 0 && oy == 0) continue;
            for (int side = 0; side < 2; ++side) {
              const int sx = side == 0 ? x + ox : x - ox;
              const int sy = side == 0 ? y + oy : y - oy;
              SideState& st = state[side];
              if (sx < 0 || sy < 0 || sx >= width || sy >= height) {
                st.depth_view = -1.0f;  // off screen: nothing known, nothing connects
                continue;
              }
              const Texel& tx = texels[size_t(sy) * size_t(width) + size_t(sx)];
              if (tx.depth_view < 0.0f) {  // background: no occluder
                st.depth_view = -1.0f;
                continue;
              }
              const float ex = tx.x - origin.x, ey = tx.y - origin.y, ez = tx.z - origin.z;
              // A tap on or below the tangent plane cannot occlude the hemisphere (nor can
              // the rest of its segment, which runs away from the eye, i.e. further down).
              // Testing in 3D first matters: rounding taps to pixel centres moves them off
              // the slice, and their slice angle alone would put tilted planes above
              // their own tangent line.
              if (!(ex * normal.x + ey * normal.y + ez * normal.z > 0.0f)) {
                // Connects at the tangent limit: u = 1 on the positive side, 0 on the other.
                const float u_lim = side == 0 ? 1.0f : 0.0f;
                st = SideState{tx.depth_view, u_lim, u_lim, &tx, true};
                continue;
              }
              // The tap in the slice's orthonormal frame (view, direction, axis): the slice
              // plane holds the first two coordinates, so the projection onto the plane is
              // dropping the third (no 3D projection per tap).
              const float dv = ex * view.x + ey * view.y + ez * view.z;
              const float dd = ex * dir.x + ey * dir.y + ez * dir.z;
              const float da = ex * axis.x + ey * axis.y + ez * axis.z;
              const float dist_slice2 = dv * dv + dd * dd;
              if (!(dist_slice2 > 0.0f)) continue;
              const float dist2 = dist_slice2 + da * da;
              // The tap's angle in the slice: of its projection onto the slice plane.
              const float tap_cos = dv / std::sqrt(dist_slice2);
              if (k.height_field) {
                // Height-field horizon, weighted by the distance falloff.
                const float w = falloff(std::sqrt(dist2));
                float& horizon_cos = side == 0 ? horizon_cos_pos : horizon_cos_neg;
                const float low_cos = side == 0 ? low_cos_pos : low_cos_neg;
                horizon_cos = std::max(horizon_cos, low_cos + (tap_cos - low_cos) * w);
                continue;
              }
              // The bent normal's horizon in the mask model: taps within the radius.
              if (dist2 <= r2) {
                float& horizon_cos = side == 0 ? horizon_cos_pos : horizon_cos_neg;
                horizon_cos = std::max(horizon_cos, tap_cos);
              }

              // Occluder segment tap + t r, t in [0, thickness], r = the tap's view ray
              // direction (away from the eye), clipped to |delta + t r| <= radius; r in the
              // slice frame too (the tap's frame coordinates are the origin's plus delta's).
              float rv = ray_ortho_v, rd = ray_ortho_d, ra = ray_ortho_a;
              if (perspective) {
                const float pv = origin_v + dv, pd = origin_d + dd, pa = origin_a + da;
                const float inv_len = 1.0f / std::sqrt(pv * pv + pd * pd + pa * pa);
                rv = pv * inv_len;
                rd = pd * inv_len;
                ra = pa * inv_len;
              }
              const float b = dv * rv + dd * rd + da * ra;
              const float c = dist2 - r2;
              const float disc = b * b - c;
              float u0 = 1.0f, u1 = 0.0f;  // empty
              if (disc >= 0.0f) {
                const float root = std::sqrt(disc);
                const float t0 = std::max(0.0f, -b - root);
                // With a back-face layer (AoInputs::depth_back_view) the segment is the
                // tap's own thickness, back - front in planar depth, as a length along r:
                // divided by |r.z| (= depth / |tap| in perspective, 1 orthographic).
                float thickness = k.thickness_world;
                if (back != nullptr) {
                  const float d_back = back->ptr<float>(sy)[sx];
                  const float planar = d_back > tx.depth_view ? d_back - tx.depth_view : 0.0f;
                  thickness = perspective ? planar *
                                                std::sqrt(tx.x * tx.x + tx.y * tx.y + tx.z * tx.z) /
                                                tx.depth_view
                                          : planar;
                }
                const float t1 = std::min(thickness, -b + root);
                if (t1 >= t0) {
                  // Cosines and sines (unsigned angles from the view vector) of the segment's
                  // two ends in the slice plane: sin = |direction coordinate| / length.
                  const float e0v = dv + t0 * rv, e0d = dd + t0 * rd;
                  const float e1v = dv + t1 * rv, e1d = dd + t1 * rd;
                  const float inv0 = 1.0f / std::sqrt(e0v * e0v + e0d * e0d);
                  const float inv1 = 1.0f / std::sqrt(e1v * e1v + e1d * e1d);
                  const float c0 = std::clamp(e0v * inv0, -1.0f, 1.0f);
                  const float c1 = std::clamp(e1v * inv1, -1.0f, 1.0f);
                  const float s0 = std::min(std::abs(e0d) * inv0, 1.0f);
                  const float s1 = std::min(std::abs(e1d) * inv1, 1.0f);
                  // Unsigned angles a = acos(c) of the two ends, ordered, clipped to the
                  // hemisphere's limit on this side (n + pi/2 on +, pi/2 - n on -), whose
                  // sine is cos n.
                  const float lim = side == 0 ? lim_pos : lim_neg;
                  const float cos_lim = side == 0 ? low_cos_pos : low_cos_neg;
                  const bool first_higher = c0 >= c1;  // a(ca) <= a(cb)
                  const float ca = first_higher ? c0 : c1, sa = first_higher ? s0 : s1;
                  float cb = first_higher ? c1 : c0, sb = first_higher ? s1 : s0;
                  if (ca > cos_lim) {
                    if (cb < cos_lim) cb = cos_lim, sb = std::abs(cos_n);
                    const float aa = std::min(fast_acos(ca), lim), ab = std::min(fast_acos(cb), lim);
                    if (side == 0) {
                      u0 = (weight_neg + inner_integral(aa, ca, sa, cos_n, sin_n)) * inv_total;
                      u1 = (weight_neg + inner_integral(ab, cb, sb, cos_n, sin_n)) * inv_total;
                    } else {
                      // Signed angle -a: the weight of [-a, 0] comes off the negative side.
                      u0 = (weight_neg - inner_integral(-ab, cb, -sb, cos_n, sin_n)) * inv_total;
                      u1 = (weight_neg - inner_integral(-aa, ca, -sa, cos_n, sin_n)) * inv_total;
                    }
                  }
                }
              }
              if (u0 > u1) {  // beyond the radius: nothing to occlude, nothing to connect
                st.depth_view = -1.0f;
                continue;
              }
              float h0 = u0, h1 = u1;
              bool connected = false;
              if (st.depth_view >= 0.0f) {
                const Texel& pv = *st.texel;
                if (st.below) {
                  // From the tangent plane: only when the two points are within the
                  // thickness of each other in 3D (a wall standing on the floor), never
                  // across the gap under a floating object.
                  const float ddx = tx.x - pv.x, ddy = tx.y - pv.y, ddz = tx.z - pv.z;
                  connected = ddx * ddx + ddy * ddy + ddz * ddz <= k.thickness_world * k.thickness_world;
                } else {
                  connected = std::abs(tx.depth_view - st.depth_view) <= k.thickness_world ||
                              coplanar(pv, tx, k.thickness_world);
                }
              }
              if (connected) {
                h0 = std::min(h0, st.u0);
                h1 = std::max(h1, st.u1);
              }
              occupied |= sector_bits(h0, h1);
              st = SideState{tx.depth_view, u0, u1, &tx, false};
            }
          }

          const float pn_len = sl.projected_normal_length;
          float visible;
          if (k.height_field) {
            // Horizon angles (GTAO Alg. 1 line 27): positive side +acos, negative -acos.
            const float h_pos = fast_acos(horizon_cos_pos);
            const float h_neg = -fast_acos(horizon_cos_neg);
            const float sp = std::sqrt(std::max(0.0f, 1.0f - horizon_cos_pos * horizon_cos_pos));
            const float sm = -std::sqrt(std::max(0.0f, 1.0f - horizon_cos_neg * horizon_cos_neg));
            visible = inner_integral(h_pos, horizon_cos_pos, sp, cos_n, sin_n) +
                      inner_integral(h_neg, horizon_cos_neg, sm, cos_n, sin_n);
          } else {
            const int free_sectors = kSectors - std::popcount(occupied);
            visible = weight_total * float(free_sectors) * (1.0f / kSectors);
          }
          visible_sum += pn_len * visible;
          open_sum += pn_len * weight_total;

          // Bent normal between the horizons: h_pos = acos(cp) in [0, pi] has sin >= 0,
          // h_neg = -acos(cm) has sin <= 0.
          const float cp = horizon_cos_pos, sp = std::sqrt(std::max(0.0f, 1.0f - cp * cp));
          const float cm = horizon_cos_neg, sm = -std::sqrt(std::max(0.0f, 1.0f - cm * cm));
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
