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
//
// The code follows the passes (as XeGTAO's): the settings become Constants once; the frame
// becomes packed texels (build_texels); tiles of pixels are scheduled with the next row's
// taps planned and each pixel's taps prefetched (shade_tile, plan_pixel, prefetch_pixel);
// a row's points and slice bases are computed across its pixels (plan_bases, slice_basis);
// per pixel (shade_pixel) and slice (integrate_slice): either the height-field horizons
// and their integral (height_field_horizons, height_field_integral) or the visibility mask
// and its integral (visibility_mask, visibility_mask_integral), and the slice's bent normal
// (slice_bent_normal); a row's sums become AO and bent normal in finish_row.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/ao_gtao.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <array>
#include <bit>
#include <numbers>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "core/parallel.h"
#include "core/uninitialized.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::detail::HWY_NAMESPACE {
namespace {

constexpr int kSectors = 64;

// Tiles the pixels are shaded in, pixels (see shade_tile). 64 wide: a row of a tile is
// planned while the row above is shaded, and 64 px of shading hide the wait better than
// 32; 32 tall: the strips of the parallel loop, whose count balances the threads.
constexpr int kTileWidthPx = 64;
constexpr int kTileHeightPx = 32;

// When a pixel's tap indices are kept (kKeptChunks), its taps' texels are asked for this
// many pixels before it is shaded, not a whole row before: a row's taps (64 px x 32 taps x
// 64 B at medium) overflow the 32 KiB first-level cache before they are read, four pixels'
// (8 KiB) do not, and four pixels of shading still cover the wait for the next cache level.
constexpr int kPrefetchAheadPx = 4;

// Steps whose taps are read together, before their arithmetic (see chunk_indices).
constexpr int kChunkSteps = 8;

// Sets the sectors whose centres lie in [u0, u1] (fractions of the slice measure).
inline uint64_t sector_bits(float u0, float u1) {
  const int k0 = std::max(0, int(std::ceil(u0 * kSectors - 0.5f)));
  const int k1 = std::min(kSectors - 1, int(std::floor(u1 * kSectors - 0.5f)));
  if (k1 < k0) return 0;
  const int count = k1 - k0 + 1;
  const uint64_t run = count >= 64 ? ~uint64_t(0) : ((uint64_t(1) << count) - 1);
  return run << k0;
}

// What a tap reads from the pixel it lands in, in two planes: the view-space position and
// the planar depth (negative on masked pixels: no occluder there) in 16 bytes (one load,
// four texels per cache line), read by every tap; the normal and its tangent plane, read
// only by the connection rule's coplanar test. Taps land anywhere within the radius, so
// the bytes per tap set how much of the frame stays in cache.
struct Texel {
  float x, y, z, depth_view;
};
struct TexelPlane {
  float nx, ny, nz, plane_c;  // unit normal and its tangent plane dot(n, x) = plane_c
};

void build_texels(const AoInputs& in, UninitializedVector<Texel>& texels, UninitializedVector<TexelPlane>& planes,
                  int nthreads) {
  const int width = in.depth_view.cols;
  // Before the parallel loop, which writes every element (not zeroed first).
  texels.resize(size_t(width) * size_t(in.depth_view.rows));
  planes.resize(texels.size());
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      const cv::Vec3f* pos_row = in.position_view.ptr<cv::Vec3f>(y);
      const cv::Vec3f* nor_row = in.normal_view.ptr<cv::Vec3f>(y);
      Texel* out = texels.data() + size_t(y) * size_t(width);
      TexelPlane* out_plane = planes.data() + size_t(y) * size_t(width);
      for (int x = 0; x < width; ++x) {
        const cv::Vec3f& p = pos_row[x];
        const cv::Vec3f& n = nor_row[x];
        out[x] = mask_row[x] ? Texel{p[0], p[1], p[2], depth_row[x]} : Texel{0.0f, 0.0f, 0.0f, -1.0f};
        out_plane[x] = mask_row[x] ? TexelPlane{n[0], n[1], n[2], n.dot(p)} : TexelPlane{0.0f, 0.0f, 0.0f, 0.0f};
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
inline bool coplanar(const TexelPlane& a, const TexelPlane& b, const Texel& b_pos, float tol) {
  return a.nx * b.nx + a.ny * b.ny + a.nz * b.nz >= kCoplanarMinCos &&
         std::abs(a.nx * b_pos.x + a.ny * b_pos.y + a.nz * b_pos.z - a.plane_c) <= tol;
}

// A side's last tap, for the connection rule (top of this file): its depth and its
// occluded interval in fractions of the slice measure (u0 > u1: no interval).
struct SideState {
  float depth_view = -1.0f;  // < 0: no previous tap to connect to
  float u0 = 1.0f, u1 = 0.0f;
  size_t texel = 0;  // its index in the texel planes
  bool below = false;  // the tap was on or below the tangent plane (interval at the limit)
};

// Lanes of a chunk of taps: step j0 + jj of side s (0: +direction, 1: -direction) is lane
// s * kChunkSteps + jj. Every lane is computed (unused ones for nobody), so the arithmetic
// runs in full vector registers without a remainder.
constexpr int kChunkTaps = 2 * kChunkSteps;

// Chunks per pixel (slices x chunks per slice) whose tap indices, computed when the row is
// planned, are kept for the prefetch and the shading: 6 covers the low (1 x 6 steps),
// medium (2 x 8) and high (3 x 16) presets (two rows of 37 KiB); ultra's pixels (6 x 16)
// compute their indices again and are prefetched a row ahead.
constexpr int kKeptChunks = 6;

// Slices per pixel whose bases are computed for a whole tile row before it is shaded, in
// loops over the row's pixels that vectorise (plan_bases): 3 covers the low, medium and
// high presets (a row's bases: 15 KiB); with more, each basis is computed at its slice.
constexpr int kKeptSlices = 3;

// The side constants per lane.
struct TapLanes {
  alignas(32) float sign[kChunkTaps];     // +1 on the positive side, -1 on the negative
  alignas(32) float lim[kChunkTaps];      // the hemisphere's limit angle on the lane's side
  alignas(32) float cos_lim[kChunkTaps];  // its cosine
};

// The taps of a chunk: texel index (-1: off screen or past the last step).
struct TapChunk {
  alignas(32) int32_t index[kChunkTaps];
  alignas(32) int32_t skip[kChunkSteps];  // the step has no tap: its offset rounds to (0, 0)
};

// The pixel's point and the slice's frame, as the taps' arithmetic needs them.
struct SliceFrame {
  glm::vec3 origin, normal, view, dir, axis;
  float origin_v, origin_d, origin_a;           // the origin in the slice frame
  float ray_ortho_v, ray_ortho_d, ray_ortho_a;  // the orthographic view ray in it
  float r2;                                     // radius_world^2
  float cos_n, sin_n, abs_cos_n;                // the projected normal's angle n
  float weight_neg, inv_total;                  // slice measure of the negative side, 1 / total
  // The occluder segments' lengths: per texel (build_texel_thickness) or, when null, one.
  const float* texel_thickness;
  float thickness_world;
};

// Per lane: the tap's coordinates in the slice frame, its height above the tangent plane
// (only its sign is used), its squared distance in the slice plane and in 3D, the cosine of
// its angle in the slice, and the occluded interval [u0, u1] of its segment (u0 > u1: none).
struct TapGeometry {
  alignas(32) float dv[kChunkTaps], dd[kChunkTaps], da[kChunkTaps];  // in the slice frame
  alignas(32) float height[kChunkTaps];
  alignas(32) float dist_slice2[kChunkTaps];
  alignas(32) float dist2[kChunkTaps];
  alignas(32) float tap_cos[kChunkTaps];
  alignas(32) float u0[kChunkTaps];
  alignas(32) float u1[kChunkTaps];
};

// The grid the taps land on and the pattern's counts.
struct TapGrid {
  int width, height;
  int slices, steps;
};

// Texel indices of the taps of steps j0 .. j0 + kChunkSteps - 1 of slice i of pixel (x, y)
// in the lanes of TapChunk (-1: off screen or past the last step), and per step whether
// it has no tap. d: the slice's screen direction; every lane alike, so the loop vectorises.
inline void tap_indices(const TapGrid& g, float step_noise, float radius_px, int x, int y, int i,
                        glm::vec2 d, int j0, int32_t* __restrict index, int32_t* __restrict skip) {
  for (int jj = 0; jj < kChunkSteps; ++jj) {
    const int j = j0 + jj;
    // R1 sequence per step (Roberts 2018) on top of the pixel's noise.
    float t = step_noise + float(i + j * g.slices) * 0.618033988749895f;
    t -= std::floor(t);
    t = (float(j) + t) / float(g.steps);
    // Uniform in screen distance (distribution power 1). XeGTAO's power 2 puts taps near
    // the centre; against the ray-marched reference on the shared frames (cornell,
    // greeble, depthgap) power 1 halved the error at 8 steps (MAE 0.057 -> 0.040 on
    // cornell): far taps carry walls seen at grazing angles, whose occlusion the dense
    // near taps never see.
    const float dist_px = kMinTapDistancePx + t * (radius_px - kMinTapDistancePx);
    // The positive side's offset; the negative side's is its negation.
    const int ox = round_to_int(d.x * dist_px), oy = round_to_int(d.y * dist_px);
    const bool used = j < g.steps;
    skip[jj] = (ox == 0) & (oy == 0);
    const int px = x + ox, py = y + oy, nx = x - ox, ny = y - oy;
    const bool pos_on = used & (px >= 0) & (py >= 0) & (px < g.width) & (py < g.height);
    const bool neg_on = used & (nx >= 0) & (ny >= 0) & (nx < g.width) & (ny < g.height);
    index[jj] = pos_on ? py * g.width + px : -1;
    index[kChunkSteps + jj] = neg_on ? ny * g.width + nx : -1;
  }
}

// Each texel's occluder segment length from the second depth layer (AoInputs::
// depth_back_view), once per texel rather than per tap: back - front in planar depth, as a
// length along its view ray, i.e. divided by |r.z| (= depth / |tap| in perspective, 1
// orthographic). Background texels are never read.
void build_texel_thickness(const AoInputs& in, const cv::Mat& back, const UninitializedVector<Texel>& texels,
                           bool perspective, UninitializedVector<float>& thickness, int nthreads) {
  const int width = in.depth_view.cols;
  thickness.resize(texels.size());  // before the parallel loop, which writes every element
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* back_row = back.ptr<float>(y);
      for (int x = 0; x < width; ++x) {
        const size_t index = size_t(y) * size_t(width) + size_t(x);
        const Texel& tx = texels[index];
        const float planar = back_row[x] > tx.depth_view ? back_row[x] - tx.depth_view : 0.0f;
        const float tap_length = std::sqrt(tx.x * tx.x + tx.y * tx.y + tx.z * tx.z);
        thickness[index] = perspective ? planar * tap_length / tx.depth_view : planar;
      }
    }
  });
}

// The taps' coordinates in the slice frame, every lane alike (no branches: the loop
// vectorises). Returns bit s set when some lane of side s is an occluder the ordered pass
// reads (on screen, foreground, above the tangent plane, off the slice's centre).
[[gnu::always_inline]] inline int slice_coordinates(const Texel* texels, const TapChunk& taps,
                                                    const SliceFrame& f, TapGeometry& __restrict g) {
  // The frame's values as locals: selects between them then need no conditional loads,
  // which would keep the loop from vectorising.
  const float ox = f.origin.x, oy = f.origin.y, oz = f.origin.z;
  const float nx = f.normal.x, ny = f.normal.y, nz = f.normal.z;
  const float vx = f.view.x, vy = f.view.y, vz = f.view.z;
  const float dx = f.dir.x, dy = f.dir.y, dz = f.dir.z;
  const float ax = f.axis.x, ay = f.axis.y, az = f.axis.z;
  int occluders = 0;
  for (int m = 0; m < kChunkTaps; ++m) {
    // Lanes without a texel compute on texel 0, for nobody.
    const Texel& tx = texels[taps.index[m] >= 0 ? taps.index[m] : 0];
    const float ex = tx.x - ox, ey = tx.y - oy, ez = tx.z - oz;
    const float height = ex * nx + ey * ny + ez * nz;
    // The tap in the slice's orthonormal frame (view, direction, axis): the slice plane
    // holds the first two coordinates, so the projection onto the plane is dropping the
    // third (no 3D projection per tap).
    const float dv = ex * vx + ey * vy + ez * vz;
    const float dd = ex * dx + ey * dy + ez * dz;
    const float da = ex * ax + ey * ay + ez * az;
    const float dist_slice2 = dv * dv + dd * dd;
    g.dv[m] = dv;
    g.dd[m] = dd;
    g.da[m] = da;
    g.height[m] = height;
    g.dist_slice2[m] = dist_slice2;
    g.dist2[m] = dist_slice2 + da * da;
    // The tap's angle in the slice: of its projection onto the slice plane.
    g.tap_cos[m] = dv / std::sqrt(dist_slice2);
    occluders |= int((taps.index[m] >= 0) & (tx.depth_view >= 0.0f) & (height > 0.0f) & (dist_slice2 > 0.0f))
                 << (m / kChunkSteps);
  }
  return occluders;
}

// The occluded interval [u0, u1] of the occluder segment of each lane of one side (lanes
// first_lane .. first_lane + kChunkSteps - 1), in fractions of the slice measure (the
// visibility mask's sectors), every lane alike (u0 > u1: no interval).
template <bool perspective, bool per_texel_thickness>
[[gnu::always_inline]] inline void segment_intervals(const TapChunk& taps, const TapLanes& lanes,
                                                     const SliceFrame& f, int first_lane,
                                                     TapGeometry& __restrict g) {
  const float* texel_thickness = f.texel_thickness;
  const float thickness_world = f.thickness_world;
  const float origin_v = f.origin_v, origin_d = f.origin_d, origin_a = f.origin_a;
  const float ray_ortho_v = f.ray_ortho_v, ray_ortho_d = f.ray_ortho_d, ray_ortho_a = f.ray_ortho_a;
  const float r2 = f.r2, cos_n = f.cos_n, sin_n = f.sin_n, abs_cos_n = f.abs_cos_n;
  const float weight_neg = f.weight_neg, inv_total = f.inv_total;
  for (int m = first_lane; m < first_lane + kChunkSteps; ++m) {
    const float dv = g.dv[m], dd = g.dd[m], da = g.da[m], dist2 = g.dist2[m];
    // Occluder segment tap + t r, t in [0, thickness], r = the tap's view ray direction
    // (away from the eye), clipped to |delta + t r| <= radius; r in the slice frame too
    // (the tap's frame coordinates are the origin's plus delta's).
    const float pv = origin_v + dv, pd = origin_d + dd, pa = origin_a + da;
    const float inv_len = 1.0f / std::sqrt(pv * pv + pd * pd + pa * pa);
    float rv = ray_ortho_v, rd = ray_ortho_d, ra = ray_ortho_a;
    if constexpr (perspective) {
      rv = pv * inv_len;
      rd = pd * inv_len;
      ra = pa * inv_len;
    }
    const float b = dv * rv + dd * rd + da * ra;
    const float c = dist2 - r2;
    const float disc = b * b - c;
    // disc < 0 (the ray misses the sphere): root is NaN, the lane is not hit below.
    const float root = std::sqrt(disc);
    // Lanes without a texel read texel 0's, for nobody (no conditional load: the loop
    // stays vectorised, the read a gather next to the texel's).
    float thickness = thickness_world;
    if constexpr (per_texel_thickness) thickness = texel_thickness[std::max(taps.index[m], 0)];
    const float t0 = std::max(0.0f, -b - root);
    const float t1 = std::min(thickness, -b + root);
    // Cosines and sines (unsigned angles from the view vector) of the segment's two ends
    // in the slice plane: sin = |direction coordinate| / length.
    const float e0v = dv + t0 * rv, e0d = dd + t0 * rd;
    const float e1v = dv + t1 * rv, e1d = dd + t1 * rd;
    const float inv0 = 1.0f / std::sqrt(e0v * e0v + e0d * e0d);
    const float inv1 = 1.0f / std::sqrt(e1v * e1v + e1d * e1d);
    const float c0 = std::clamp(e0v * inv0, -1.0f, 1.0f);
    const float c1 = std::clamp(e1v * inv1, -1.0f, 1.0f);
    const float s0 = std::min(std::abs(e0d) * inv0, 1.0f);
    const float s1 = std::min(std::abs(e1d) * inv1, 1.0f);
    // Unsigned angles a = acos(c) of the two ends, ordered, clipped to the hemisphere's
    // limit on this side (n + pi/2 on +, pi/2 - n on -), whose sine is cos n.
    const bool first_higher = c0 >= c1;  // a(ca) <= a(cb)
    const float ca = first_higher ? c0 : c1, sa = first_higher ? s0 : s1;
    const float cos_lim = lanes.cos_lim[m], lim = lanes.lim[m];
    const float c_far = first_higher ? c1 : c0, s_far = first_higher ? s1 : s0;
    const bool clip = c_far < cos_lim;
    const float cb = clip ? cos_lim : c_far, sb = clip ? abs_cos_n : s_far;
    const float aa = std::min(fast_acos(ca), lim), ab = std::min(fast_acos(cb), lim);
    // Positive side: u = measure of the negative side + of [0, a]. Negative side (signed
    // angle -a): the weight of [-a, 0] comes off the negative side's, and the end nearer
    // the view vector is the higher u.
    const float sign = lanes.sign[m];
    const bool pos = sign > 0.0f;
    const float h_lo = pos ? aa : ab, c_lo = pos ? ca : cb, s_lo = pos ? sa : sb;
    const float h_hi = pos ? ab : aa, c_hi = pos ? cb : ca, s_hi = pos ? sb : sa;
    const float i_lo = sign * inner_integral(sign * h_lo, c_lo, sign * s_lo, cos_n, sin_n);
    const float i_hi = sign * inner_integral(sign * h_hi, c_hi, sign * s_hi, cos_n, sin_n);
    const float u0 = (weight_neg + i_lo) * inv_total;
    const float u1 = (weight_neg + i_hi) * inv_total;
    const bool hit = (disc >= 0.0f) & (t1 >= t0) & (ca > cos_lim);
    g.u0[m] = hit ? u0 : 1.0f;  // empty: u0 > u1
    g.u1[m] = hit ? u1 : 0.0f;
  }
}

// The taps' arithmetic, every lane alike. Lanes whose tap is not used later (background,
// below the tangent plane, zero distance) compute values nobody reads; with segments =
// false (the height-field model) the occluder segments are skipped, and so they are on a
// side without an occluder (its taps all on or below the tangent plane: the common case on
// open surfaces and on the lower side of a slope; that side's u0 and u1 are then left
// unwritten, and the ordered pass reads them only for occluders). Returns bit s set when
// side s has an occluder (see slice_coordinates).
// Not inlined: inlined into the pixel loop, its selects no longer become blends and the
// loops stay scalar.
template <bool perspective, bool segments>
[[gnu::noinline]]
int tap_geometry(const Texel* texels, const TapChunk& taps, const TapLanes& lanes,
                 const SliceFrame& f, TapGeometry& __restrict g) {
  const int occluders = slice_coordinates(texels, taps, f, g);
  if (!segments) return occluders;
  for (int side = 0; side < 2; ++side) {
    if (!((occluders >> side) & 1)) continue;
    if (f.texel_thickness != nullptr) segment_intervals<perspective, true>(taps, lanes, f, side * kChunkSteps, g);
    else segment_intervals<perspective, false>(taps, lanes, f, side * kChunkSteps, g);
  }
  return occluders;
}

// The settings turned into what the passes read, once per call (XeGTAO's GTAOConstants).
struct Constants {
  int slices;
  int steps;
  float radius_world;
  float max_radius_px;
  float thickness_world;
  bool height_field;  // thickness_world = inf: the paper's height-field occluders
  float depth_bias_relative;
  uint32_t seed;
  bool multibounce;
  bool perspective;
  float r2;  // radius_world^2
  Falloff falloff;
  ScreenToView screen_to_view;
  TapGrid grid;
  int chunks_per_slice;
  bool keep_indices;  // a pixel's tap indices fit in its tile row (kKeptChunks)
  bool keep_bases;    // a pixel's slice bases fit in its row's (kKeptSlices)
  // Slice angles i pi / slices as (cos, sin), rotated per pixel by one angle: no trig per
  // slice in the pixel loop.
  std::vector<std::array<float, 2>> slice_rot;

  Constants(const AoInputs& in, const AoSettings& s)
      : slices(s.directions),
        steps(s.steps),
        radius_world(s.radius_world),
        max_radius_px(s.max_radius_px),
        thickness_world(s.thickness_world),
        height_field(!std::isfinite(s.thickness_world)),
        depth_bias_relative(s.depth_bias_relative),
        seed(s.seed),
        multibounce(s.multibounce && in.albedo != nullptr && !in.albedo->empty()),
        perspective(in.camera.is_perspective()),
        r2(s.radius_world * s.radius_world),
        falloff(s.radius_world, s.falloff_fraction),
        screen_to_view(in.camera),
        grid{in.depth_view.cols, in.depth_view.rows, s.directions, s.steps},
        chunks_per_slice((s.steps + kChunkSteps - 1) / kChunkSteps),
        keep_indices(slices * chunks_per_slice <= kKeptChunks),
        keep_bases(slices <= kKeptSlices),
        slice_rot(size_t(s.directions)) {
    for (int i = 0; i < slices; ++i) {
      // The float pi widened to double (the slice angles' bits depend on it).
      const double a = double(i) * double(std::numbers::pi_v<float>) / double(slices);
      slice_rot[size_t(i)] = {float(std::cos(a)), float(std::sin(a))};
    }
  }
};

// The frame as the taps read it: the G-buffer views, their texels, and the second depth
// layer when the visibility mask's segments take their thickness from it.
struct Frame {
  const AoInputs& in;
  UninitializedVector<Texel> texels;
  UninitializedVector<TexelPlane> planes;
  // Per texel, its occluder segment's length from the second depth layer; empty without one
  // (or with height-field occluders, which have no thickness).
  UninitializedVector<float> thickness;
};

const cv::Mat* back_layer(const AoInputs& in, const Constants& k) {
  return !k.height_field && in.depth_back_view != nullptr && !in.depth_back_view->empty() &&
                 in.depth_back_view->size() == in.depth_view.size()
             ? in.depth_back_view
             : nullptr;
}

// A pixel's tap pattern (GTAO Alg. 1 lines 5-6 and the steps' jitter): whether it has
// taps, its projected radius, its step noise and the rotation of its slices.
struct PixelTaps {
  bool has_taps = false;
  float radius_px = 0.0f;
  float step_noise = 0.0f;
  float rot_c = 1.0f, rot_s = 0.0f;
};

// A row of a tile: the pixels' tap patterns and kept tap indices (filled a row ahead, see
// shade_tile), and the shading's per-pixel sums, turned into the outputs for the whole row
// at once (the divisions and square roots of the normalisation then run in vector lanes
// instead of ending each pixel's dependency chain).
enum : uint8_t { kBackground, kNoTaps, kShaded };
struct TileRow {
  std::array<PixelTaps, kTileWidthPx> pixel;
  alignas(32) int32_t index[kTileWidthPx][kKeptChunks][kChunkTaps];
  alignas(32) int32_t skip[kTileWidthPx][kKeptChunks][kChunkSteps];
  alignas(32) float visible_sum[kTileWidthPx];
  alignas(32) float open_sum[kTileWidthPx];
  alignas(32) float bent_x[kTileWidthPx], bent_y[kTileWidthPx], bent_z[kTileWidthPx];
  alignas(32) uint8_t state[kTileWidthPx];
};

// Written field by field into its place in the row (a whole struct built on the stack and
// copied is read back before its parts' stores retire: a store-forwarding stall).
[[gnu::always_inline]] inline void pixel_taps(const Constants& k, const AoInputs& in, int x, int y,
                                              PixelTaps& p) {
  p.has_taps = false;
  p.radius_px = 0.0f;
  p.step_noise = 0.0f;
  p.rot_c = 1.0f;
  p.rot_s = 0.0f;
  if (!in.mask.ptr<uint8_t>(y)[x]) return;
  const float depth = in.depth_view.ptr<float>(y)[x];
  p.radius_px = projected_radius_px(in.camera, depth, k.radius_world, k.max_radius_px);
  // Below 2 px the whole occlusion sphere fits in the pixel's neighbour: no tap can see it.
  if (p.radius_px < 2.0f * kMinTapDistancePx) return;
  p.has_taps = true;
  const int nx = x - in.frame_origin_px.x, ny = y - in.frame_origin_px.y;  // the frame's pixel
  const float slice_noise = noise01(nx, ny, 0, k.seed);
  p.step_noise = noise01(nx, ny, 1, k.seed);
  // The rotation slice_noise pi / slices, in turns.
  sincos_turns(slice_noise / float(2 * k.slices), p.rot_c, p.rot_s);
}

// Screen direction of slice i (px, y down): slice angle phi in [0, pi), rotated per pixel.
[[gnu::always_inline]] inline glm::vec2 slice_direction(const Constants& k, float rot_c, float rot_s, int i) {
  const std::array<float, 2>& r = k.slice_rot[size_t(i)];
  const float cos_phi = rot_c * r[0] - rot_s * r[1];
  const float sin_phi = rot_s * r[0] + rot_c * r[1];
  return glm::vec2(cos_phi, -sin_phi);
}
[[gnu::always_inline]] inline glm::vec2 slice_direction(const Constants& k, const PixelTaps& p, int i) {
  return slice_direction(k, p.rot_c, p.rot_s, i);
}

// A pixel's point (GTAO Alg. 1 lines 1-4): its biased origin, normal and view vector.
struct PixelPoint {
  glm::vec3 origin, normal, view;
};

[[gnu::always_inline]] inline PixelPoint pixel_point(const Constants& k, const Frame& f, int x, int y) {
  const AoInputs& in = f.in;
  const float depth = in.depth_view.ptr<float>(y)[x];
  const cv::Vec3f& n_px = in.normal_view.ptr<cv::Vec3f>(y)[x];
  const Texel& centre = f.texels[size_t(y) * size_t(k.grid.width) + size_t(x)];
  const glm::vec3 p(centre.x, centre.y, centre.z);
  const glm::vec3 normal(n_px[0], n_px[1], n_px[2]);
  const glm::vec3 view = view_vector(in.camera, p);
  return {biased_origin(p, normal, depth, k.depth_bias_relative), normal, view};
}

struct RowBases;

// The pixel being shaded: where it is, its tile row (which holds its tap pattern), and its
// row's points and slice bases.
struct ShadedPixel {
  int x, y;
  const TileRow& row;
  size_t xi;
  const RowBases& bases;
};

// A slice's basis as the taps' arithmetic needs it (GTAO Alg. 1 lines 8-16), and its
// measure.
struct SliceBasis {
  SliceFrame frame;
  float pn_len;                    // |projected normal|: the slice's weight
  float weight_total;              // the slice measure between the tangent limits
  float low_cos_pos, low_cos_neg;  // the tangent limits' cosines: the lowest horizons
  float lim_pos, lim_neg;          // the hemisphere's limit angles per side
};

// What a slice adds to its pixel's point and the frame's constants: its direction and axis,
// the origin in its frame, its angle n and measures. The rest of its basis follows from
// these (slice_basis_from).
struct SliceFields {
  glm::vec3 dir, axis;
  float origin_v, origin_d, origin_a;
  float cos_n, sin_n;
  float weight_neg, inv_total;
  float pn_len, weight_total;
  float lim_pos, lim_neg;
};

[[gnu::always_inline]] inline SliceFields slice_fields(const Constants& k, const PixelPoint& px, glm::vec2 d) {
  const Slice sl = make_slice(k.screen_to_view(d.x, d.y), px.view, px.normal);
  // n = sign acos(cos_n), so sin n = sign sqrt(1 - cos_n^2) and the tangent limits
  // n +- pi/2 have cos = -+sin n: no trig per slice.
  const float cos_n = sl.cos_n;
  const float sin_n = std::copysign(std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n)), sl.n);
  // Slice measure of the negative side and in total (inner integral at n +- pi/2).
  const float weight_neg = inner_integral(sl.n - kHalfPi, sin_n, -cos_n, cos_n, sin_n);
  const float weight_total = cos_n + sl.n * sin_n;
  const float inv_total = weight_total > 0.0f ? 1.0f / weight_total : 0.0f;
  const float lim_pos = sl.n + kHalfPi, lim_neg = kHalfPi - sl.n;
  // The origin in the slice's orthonormal frame (per slice, so that each tap needs three dot
  // products).
  const glm::vec3 &origin = px.origin, &dir = sl.direction, &axis = sl.axis;
  return {dir,    axis,      glm::dot(origin, px.view), glm::dot(origin, dir), glm::dot(origin, axis),
          cos_n,  sin_n,     weight_neg, inv_total, sl.projected_normal_length, weight_total,
          lim_pos, lim_neg};
}

// The basis of a slice of the pixel at px: its fields, with the orthographic view ray in the
// slice's frame, the tangent limits' cosines (-+sin n) and the frame's constants.
[[gnu::always_inline]] inline SliceBasis slice_basis_from(const Constants& k, const Frame& f, const PixelPoint& px,
                                                          const SliceFields& s) {
  return {SliceFrame{px.origin, px.normal, px.view, s.dir, s.axis, s.origin_v, s.origin_d, s.origin_a, -px.view.z,
                     -s.dir.z, -s.axis.z, k.r2, s.cos_n, s.sin_n, std::abs(s.cos_n), s.weight_neg, s.inv_total,
                     f.thickness.empty() ? nullptr : f.thickness.data(), k.thickness_world},
          s.pn_len, s.weight_total, -s.sin_n, s.sin_n, s.lim_pos, s.lim_neg};
}

[[gnu::always_inline]] inline SliceBasis slice_basis(const Constants& k, const Frame& f, const PixelPoint& px,
                                                     glm::vec2 d) {
  return slice_basis_from(k, f, px, slice_fields(k, px, d));
}

// Per lane of a chunk (side s, step j0 + jj at lane s * kChunkSteps + jj): the side's sign
// of the angle, its hemisphere limit and the limit's cosine.
inline void fill_tap_lanes(const SliceBasis& b, TapLanes& lanes) {
  for (int m = 0; m < kChunkTaps; ++m) {
    const bool pos = m < kChunkSteps;
    lanes.sign[m] = pos ? 1.0f : -1.0f;
    lanes.lim[m] = pos ? b.lim_pos : b.lim_neg;
    lanes.cos_lim[m] = pos ? b.low_cos_pos : b.low_cos_neg;
  }
}

// The points and slice bases of a tile row's pixels, field by field (slice i of pixel xi at
// [i][xi]), so that the loops computing them run over the pixels in vector lanes: a basis
// is a chain of divisions and square roots per pixel and slice, which one pixel at a time
// would run in scalar registers.
struct RowBases {
  alignas(64) float origin[3][kTileWidthPx], normal[3][kTileWidthPx], view[3][kTileWidthPx];
  alignas(64) float rot_c[kTileWidthPx], rot_s[kTileWidthPx];  // the pixels' slice rotation
  alignas(64) float dir[kKeptSlices][3][kTileWidthPx], axis[kKeptSlices][3][kTileWidthPx];
  alignas(64) float origin_v[kKeptSlices][kTileWidthPx], origin_d[kKeptSlices][kTileWidthPx],
      origin_a[kKeptSlices][kTileWidthPx];
  alignas(64) float cos_n[kKeptSlices][kTileWidthPx], sin_n[kKeptSlices][kTileWidthPx];
  alignas(64) float weight_neg[kKeptSlices][kTileWidthPx], inv_total[kKeptSlices][kTileWidthPx];
  alignas(64) float pn_len[kKeptSlices][kTileWidthPx], weight_total[kKeptSlices][kTileWidthPx];
  alignas(64) float lim_pos[kKeptSlices][kTileWidthPx], lim_neg[kKeptSlices][kTileWidthPx];

  void set_point(size_t xi, const PixelPoint& p) {
    for (int c = 0; c < 3; ++c) origin[c][xi] = p.origin[c], normal[c][xi] = p.normal[c], view[c][xi] = p.view[c];
  }
  PixelPoint point(size_t xi) const {
    return {{origin[0][xi], origin[1][xi], origin[2][xi]},
            {normal[0][xi], normal[1][xi], normal[2][xi]},
            {view[0][xi], view[1][xi], view[2][xi]}};
  }
  void set_fields(int i, size_t xi, const SliceFields& s) {
    for (int c = 0; c < 3; ++c) dir[i][c][xi] = s.dir[c], axis[i][c][xi] = s.axis[c];
    origin_v[i][xi] = s.origin_v, origin_d[i][xi] = s.origin_d, origin_a[i][xi] = s.origin_a;
    cos_n[i][xi] = s.cos_n, sin_n[i][xi] = s.sin_n;
    weight_neg[i][xi] = s.weight_neg, inv_total[i][xi] = s.inv_total;
    pn_len[i][xi] = s.pn_len, weight_total[i][xi] = s.weight_total;
    lim_pos[i][xi] = s.lim_pos, lim_neg[i][xi] = s.lim_neg;
  }
  SliceBasis basis(const Constants& k, const Frame& f, int i, size_t xi) const {
    const SliceFields s{{dir[i][0][xi], dir[i][1][xi], dir[i][2][xi]},
                        {axis[i][0][xi], axis[i][1][xi], axis[i][2][xi]},
                        origin_v[i][xi], origin_d[i][xi], origin_a[i][xi], cos_n[i][xi], sin_n[i][xi],
                        weight_neg[i][xi], inv_total[i][xi], pn_len[i][xi], weight_total[i][xi],
                        lim_pos[i][xi], lim_neg[i][xi]};
    return slice_basis_from(k, f, point(xi), s);
  }
};

// The points of row y's pixels x0 .. x1 - 1 and, when kept, their slice bases, before the
// row is shaded (pixels without taps compute values nobody reads: no branch in the loops).
inline void plan_bases(const Constants& k, const Frame& f, int x0, int x1, int y, const TileRow& row, RowBases& rb) {
  const int n = x1 - x0;
  for (int xi = 0; xi < n; ++xi) rb.set_point(size_t(xi), pixel_point(k, f, x0 + xi, y));
  if (!k.keep_bases) return;
  for (int xi = 0; xi < n; ++xi) rb.rot_c[xi] = row.pixel[size_t(xi)].rot_c, rb.rot_s[xi] = row.pixel[size_t(xi)].rot_s;
  for (int i = 0; i < k.slices; ++i)
    for (int xi = 0; xi < n; ++xi) {
      const size_t x = size_t(xi);
      rb.set_fields(i, x, slice_fields(k, rb.point(x), slice_direction(k, rb.rot_c[x], rb.rot_s[x], i)));
    }
}

// The tap indices of steps j0 .. j0 + kChunkSteps - 1 of slice i: kept by the prefetch when
// they fit, computed again otherwise. The chunk's tap pixels come first, then their texels,
// then the taps' arithmetic in lanes, then the taps in order: the texel loads do not wait
// on each other's arithmetic, so their cache misses overlap (a tap's texel is anywhere
// within the radius), and the arithmetic has no branches.
[[gnu::always_inline]] inline void chunk_indices(const Constants& k, const ShadedPixel& px, int i, glm::vec2 d,
                                                 int j0, TapChunk& taps) {
  if (k.keep_indices) {
    const int c = i * k.chunks_per_slice + j0 / kChunkSteps;
    std::copy_n(px.row.index[px.xi][c], kChunkTaps, taps.index);
    std::copy_n(px.row.skip[px.xi][c], kChunkSteps, taps.skip);
  } else {
    const PixelTaps& pt = px.row.pixel[px.xi];
    tap_indices(k.grid, pt.step_noise, pt.radius_px, px.x, px.y, i, d, j0, taps.index, taps.skip);
  }
}

// A slice's horizons, per side, as cosines from the view vector.
struct Horizons {
  float cos_pos, cos_neg;
};

// Height-field horizons (GTAO Alg. 1 lines 17-26, the paper's occluder model): per side,
// the tap direction closest to the view vector, lerped towards the lowest horizon by the
// distance falloff (GTAO sec. 4.3, "Bounding the sampling area"; XeGTAO).
[[gnu::always_inline]] inline void height_field_horizons(const Constants& k, const Frame& f, const ShadedPixel& px,
                                                         int i, glm::vec2 d, const SliceBasis& b, Horizons& h) {
  TapLanes lanes;
  fill_tap_lanes(b, lanes);
  for (int j0 = 0; j0 < k.steps; j0 += kChunkSteps) {
    const int chunk = std::min(kChunkSteps, k.steps - j0);
    TapChunk taps;
    chunk_indices(k, px, i, d, j0, taps);
    TapGeometry geo;
    const int occluders = k.perspective ? tap_geometry<true, false>(f.texels.data(), taps, lanes, b.frame, geo)
                                        : tap_geometry<false, false>(f.texels.data(), taps, lanes, b.frame, geo);
    for (int side = 0; side < 2; ++side) {
      if (!((occluders >> side) & 1)) continue;  // only occluders raise the horizon
      float& horizon_cos = side == 0 ? h.cos_pos : h.cos_neg;
      const float low_cos = side == 0 ? b.low_cos_pos : b.low_cos_neg;
      for (int jj = 0; jj < chunk; ++jj) {
        const int m = side * kChunkSteps + jj;
        // No tap, off screen, background (no occluder), on or below the tangent plane (see
        // visibility_mask_tap) or on the view ray through the origin: no horizon.
        if (taps.skip[jj] || taps.index[m] < 0 || f.texels[size_t(taps.index[m])].depth_view < 0.0f ||
            !(geo.height[m] > 0.0f) || !(geo.dist_slice2[m] > 0.0f))
          continue;
        const float w = k.falloff(std::sqrt(geo.dist2[m]));
        horizon_cos = std::max(horizon_cos, low_cos + (geo.tap_cos[m] - low_cos) * w);
      }
    }
  }
}

// The height-field slice integral: the visible measure between the two horizons (GTAO
// eq. 10's inner integral per side, Alg. 1 lines 27-29); positive side +acos, negative -acos.
inline float height_field_integral(const Horizons& h, float cos_n, float sin_n) {
  const float h_pos = fast_acos(h.cos_pos);
  const float h_neg = -fast_acos(h.cos_neg);
  const float sp = std::sqrt(std::max(0.0f, 1.0f - h.cos_pos * h.cos_pos));
  const float sm = -std::sqrt(std::max(0.0f, 1.0f - h.cos_neg * h.cos_neg));
  return inner_integral(h_pos, h.cos_pos, sp, cos_n, sin_n) + inner_integral(h_neg, h.cos_neg, sm, cos_n, sin_n);
}

// The connection rule (top of this file): tap tx, at index, continues its side's last tap.
[[gnu::always_inline]] inline bool connects(const Constants& k, const Frame& f, const SideState& st,
                                            const Texel& tx, size_t index) {
  if (!(st.depth_view >= 0.0f)) return false;
  if (st.below) {
    // From the tangent plane: only when the two points are within the thickness of each
    // other in 3D (a wall standing on the floor), never across the gap under a floating
    // object.
    const Texel& pv = f.texels[st.texel];
    const float ddx = tx.x - pv.x, ddy = tx.y - pv.y, ddz = tx.z - pv.z;
    return ddx * ddx + ddy * ddy + ddz * ddz <= k.thickness_world * k.thickness_world;
  }
  return std::abs(tx.depth_view - st.depth_view) <= k.thickness_world ||
         coplanar(f.planes[st.texel], f.planes[index], tx, k.thickness_world);
}

// One tap of the visibility mask at lane m: the sectors its segment occludes (with the
// previous tap's when they connect); updates the side's last tap and the bent normal's
// horizon (the taps within the radius).
[[gnu::always_inline]] inline uint64_t visibility_mask_tap(const Constants& k, const Frame& f, const TapChunk& taps,
                                                           const TapGeometry& geo, int m, int side, SideState& st,
                                                           float& horizon_cos) {
  if (taps.index[m] < 0) {  // off screen: nothing known, nothing connects
    st.depth_view = -1.0f;
    return 0;
  }
  const size_t index = size_t(taps.index[m]);
  const Texel& tx = f.texels[index];
  const float depth_view = tx.depth_view;
  if (depth_view < 0.0f) {  // background: no occluder, nothing connects
    st.depth_view = -1.0f;
    return 0;
  }
  // A tap on or below the tangent plane cannot occlude the hemisphere (nor can the rest of
  // its segment, which runs away from the eye, i.e. further down). Testing in 3D first
  // matters: rounding taps to pixel centres moves them off the slice, and their slice
  // angle alone would put tilted planes above their own tangent line.
  if (!(geo.height[m] > 0.0f)) {
    // Connects at the tangent limit: u = 1 on the positive side, 0 on the other.
    const float u_lim = side == 0 ? 1.0f : 0.0f;
    st = SideState{depth_view, u_lim, u_lim, index, true};
    return 0;
  }
  if (!(geo.dist_slice2[m] > 0.0f)) return 0;
  if (geo.dist2[m] <= k.r2) horizon_cos = std::max(horizon_cos, geo.tap_cos[m]);
  const float u0 = geo.u0[m], u1 = geo.u1[m];
  if (u0 > u1) {  // beyond the radius: nothing to occlude, nothing to connect
    st.depth_view = -1.0f;
    return 0;
  }
  float h0 = u0, h1 = u1;
  if (connects(k, f, st, tx, index)) {
    h0 = std::min(h0, st.u0);
    h1 = std::max(h1, st.u1);
  }
  st = SideState{depth_view, u0, u1, index, false};
  return sector_bits(h0, h1);
}

// The visibility mask of a slice (Therrien et al. 2023; finite thickness_world): the
// sectors occluded by the taps' segments, side by side in order of distance.
[[gnu::always_inline]] inline uint64_t visibility_mask(const Constants& k, const Frame& f, const ShadedPixel& px,
                                                       int i, glm::vec2 d, const SliceBasis& b, Horizons& h) {
  uint64_t occupied = 0;
  SideState state[2];
  TapLanes lanes;
  fill_tap_lanes(b, lanes);
  for (int j0 = 0; j0 < k.steps; j0 += kChunkSteps) {
    const int chunk = std::min(kChunkSteps, k.steps - j0);
    TapChunk taps;
    chunk_indices(k, px, i, d, j0, taps);
    TapGeometry geo;
    const int occluders = k.perspective ? tap_geometry<true, true>(f.texels.data(), taps, lanes, b.frame, geo)
                                        : tap_geometry<false, true>(f.texels.data(), taps, lanes, b.frame, geo);
    const bool last_chunk = j0 + kChunkSteps >= k.steps;
    for (int side = 0; side < 2; ++side) {
      // A side without an occluder sets no sector and raises no horizon; its taps only
      // update the side's last tap, which nothing reads after the slice's last chunk.
      if (last_chunk && !((occluders >> side) & 1)) continue;
      SideState& st = state[side];
      float& horizon_cos = side == 0 ? h.cos_pos : h.cos_neg;
      for (int jj = 0; jj < chunk; ++jj)
        if (!taps.skip[jj])
          occupied |= visibility_mask_tap(k, f, taps, geo, side * kChunkSteps + jj, side, st, horizon_cos);
    }
  }
  return occupied;
}

// The visibility-mask slice integral: the free sectors' share of the slice measure (the
// sectors are equally spaced in it).
inline float visibility_mask_integral(uint64_t occupied, float weight_total) {
  const int free_sectors = kSectors - std::popcount(occupied);
  return weight_total * float(free_sectors) * (1.0f / kSectors);
}

// The slice's bent normal, weighted by |pn|: its cosine-weighted mean visible direction
// between the horizons (closed forms, see bent_a and bent_b). h_pos = acos(cp) in [0, pi]
// has sin >= 0, h_neg = -acos(cm) has sin <= 0.
inline glm::vec3 slice_bent_normal(const Horizons& h, const SliceBasis& b) {
  const float cos_n = b.frame.cos_n, sin_n = b.frame.sin_n;
  const float cp = h.cos_pos, sp = std::sqrt(std::max(0.0f, 1.0f - cp * cp));
  const float cm = h.cos_neg, sm = -std::sqrt(std::max(0.0f, 1.0f - cm * cm));
  const float a0 = bent_a(1.0f, 0.0f, cos_n, sin_n), b0 = bent_b(1.0f, 0.0f, cos_n, sin_n);
  const float along_view = bent_a(cp, sp, cos_n, sin_n) + bent_a(cm, sm, cos_n, sin_n) - 2.0f * a0;
  const float along_dir = bent_b(cp, sp, cos_n, sin_n) + bent_b(cm, sm, cos_n, sin_n) - 2.0f * b0;
  return b.pn_len * (along_view * b.frame.view + along_dir * b.frame.dir);
}

// A pixel's sums over its slices: the visible and the unoccluded measure, the bent normal.
struct PixelSums {
  float visible = 0.0f, open = 0.0f;
  glm::vec3 bent{0.0f};
};

// Slice i of the pixel (GTAO Alg. 1 lines 5-30): its basis, its visible measure under the
// occluder model, its bent normal.
[[gnu::always_inline]] inline void integrate_slice(const Constants& k, const Frame& f, const ShadedPixel& px, int i,
                                                   PixelSums& sums) {
  const glm::vec2 d = slice_direction(k, px.row.pixel[px.xi], i);
  const SliceBasis b = k.keep_bases ? px.bases.basis(k, f, i, px.xi) : slice_basis(k, f, px.bases.point(px.xi), d);
  Horizons h{b.low_cos_pos, b.low_cos_neg};
  float visible;
  if (k.height_field) {
    height_field_horizons(k, f, px, i, d, b, h);
    visible = height_field_integral(h, b.frame.cos_n, b.frame.sin_n);
  } else {
    visible = visibility_mask_integral(visibility_mask(k, f, px, i, d, b, h), b.weight_total);
  }
  sums.visible += b.pn_len * visible;
  sums.open += b.pn_len * b.weight_total;
  sums.bent += slice_bent_normal(h, b);
}

// One pixel (x, y), at xi in its tile row: the sums of its AO and bent normal.
[[gnu::always_inline]] inline void shade_pixel(const Constants& k, const Frame& f, int x, int y, TileRow& row,
                                               const RowBases& bases, size_t xi) {
  const AoInputs& in = f.in;
  const bool background = !in.mask.ptr<uint8_t>(y)[x];
  if (background || !row.pixel[xi].has_taps) {
    row.state[xi] = background ? kBackground : kNoTaps;
    row.visible_sum[xi] = row.open_sum[xi] = 0.0f;
    row.bent_x[xi] = row.bent_y[xi] = row.bent_z[xi] = 0.0f;
    return;
  }
  const ShadedPixel px{x, y, row, xi, bases};
  PixelSums sums;
  for (int i = 0; i < k.slices; ++i) integrate_slice(k, f, px, i, sums);
  row.state[xi] = kShaded;
  row.visible_sum[xi] = sums.visible;
  row.open_sum[xi] = sums.open;
  row.bent_x[xi] = sums.bent.x;
  row.bent_y[xi] = sums.bent.y;
  row.bent_z[xi] = sums.bent.z;
}

// The outputs of pixels x0 .. x1 - 1 of row y from their sums (no branches: the loop
// vectorises). Background: AO 1 and no bent normal; no taps: AO 1 and the normal.
inline void finish_row(const Constants& k, const AoInputs& in, AoOutput& out, int x0, int x1, int y,
                       const TileRow& row) {
  const cv::Vec3f* normal_row = in.normal_view.ptr<cv::Vec3f>(y);
  const cv::Vec3f* albedo_row = k.multibounce ? in.albedo->ptr<cv::Vec3f>(y) : nullptr;
  float* ao_row = out.ao.ptr<float>(y);
  cv::Vec3f* bent_row = out.bent_normal_view.ptr<cv::Vec3f>(y);
  const int n = x1 - x0;
  for (int xi = 0; xi < n; ++xi) {
    const int x = x0 + xi;
    const bool shaded = row.state[xi] == kShaded;
    const float visible_sum = row.visible_sum[xi], open_sum = row.open_sum[xi];
    float ao = open_sum > 0.0f ? std::clamp(visible_sum / open_sum, 0.0f, 1.0f) : 1.0f;
    ao_row[x] = shaded ? ao : 1.0f;
  }
  if (k.multibounce)
    for (int xi = 0; xi < n; ++xi) {
      const int x = x0 + xi;
      if (row.state[xi] == kShaded)
        ao_row[x] = std::min(multibounce(ao_row[x], albedo_luminance(albedo_row[x])), 1.0f);
    }
  for (int xi = 0; xi < n; ++xi) {
    const int x = x0 + xi;
    const uint8_t state = row.state[xi];
    const glm::vec3 bent(row.bent_x[xi], row.bent_y[xi], row.bent_z[xi]);
    const glm::vec3 normal(normal_row[x][0], normal_row[x][1], normal_row[x][2]);
    const float bent_len = glm::length(bent);
    glm::vec3 bn = bent_len > 1e-12f ? bent / bent_len : normal;
    bn = state == kShaded ? bn : state == kNoTaps ? normal : glm::vec3(0.0f);
    bent_row[x] = cv::Vec3f(bn.x, bn.y, bn.z);
  }
}

// Pixel (x, y)'s tap pattern, at xi in the next tile row; its tap indices are kept in the
// row when they fit (kKeptChunks), else its taps' texels are asked for now, a row ahead.
// Always inlined: the prefetches have to be issued from the tile loop itself, between the
// shading of the row above's pixels.
[[gnu::always_inline]] inline void plan_pixel(const Constants& k, const Frame& f, int x, int y, TileRow& row,
                                              size_t xi) {
  PixelTaps& p = row.pixel[xi];
  pixel_taps(k, f.in, x, y, p);
  for (int i = 0; i < k.slices && p.has_taps; ++i) {
    const glm::vec2 d = slice_direction(k, p, i);
    for (int j0 = 0; j0 < k.steps; j0 += kChunkSteps) {
      int32_t scratch_index[kChunkTaps], scratch_skip[kChunkSteps];
      const int c = i * k.chunks_per_slice + j0 / kChunkSteps;
      int32_t* index = k.keep_indices ? row.index[xi][c] : scratch_index;
      int32_t* skip = k.keep_indices ? row.skip[xi][c] : scratch_skip;
      tap_indices(k.grid, p.step_noise, p.radius_px, x, y, i, d, j0, index, skip);
      if (!k.keep_indices)
        for (int m = 0; m < kChunkTaps; ++m)
          if (index[m] >= 0) __builtin_prefetch(f.texels.data() + index[m]);
    }
  }
}

// The texels of the taps of pixel xi of a planned row (its kept tap indices), asked for a
// few pixels before it is shaded.
[[gnu::always_inline]] inline void prefetch_pixel(const Constants& k, const Frame& f, const TileRow& row, size_t xi) {
  if (!row.pixel[xi].has_taps) return;
  const int chunks = k.slices * k.chunks_per_slice;
  for (int c = 0; c < chunks; ++c)
    for (int m = 0; m < kChunkTaps; ++m) __builtin_prefetch(f.texels.data() + std::max(row.index[xi][c][m], 0));
}

// The tile [x0, x1) x [y0, y1). Each row's tap patterns are computed while the row above
// is shaded, and their texels asked for kPrefetchAheadPx pixels before their shading (a row
// ahead when the indices are not kept): a tap's texel is anywhere within the radius, mostly
// not in the nearest cache.
inline void shade_tile(const Constants& k, const Frame& f, AoOutput& out, int x0, int x1, int y0, int y1) {
  TileRow rows[2];
  TileRow* shaded_row = &rows[0];
  TileRow* next_row = &rows[1];
  RowBases bases;
  for (int y = y0; y <= y1; ++y) {
    if (y > y0) plan_bases(k, f, x0, x1, y - 1, *shaded_row, bases);
    if (y > y0 && k.keep_indices)
      for (int x = x0; x < std::min(x0 + kPrefetchAheadPx, x1); ++x) prefetch_pixel(k, f, *shaded_row, size_t(x - x0));
    for (int x = x0; x < x1; ++x) {
      const size_t xi = size_t(x - x0);
      if (y < y1) plan_pixel(k, f, x, y, *next_row, xi);
      if (y > y0) {
        if (k.keep_indices && x + kPrefetchAheadPx < x1) prefetch_pixel(k, f, *shaded_row, xi + kPrefetchAheadPx);
        shade_pixel(k, f, x, y - 1, *shaded_row, bases, xi);
      }
    }
    if (y > y0) finish_row(k, f.in, out, x0, x1, y - 1, *shaded_row);
    std::swap(shaded_row, next_row);
  }
}

}  // namespace

void ao_gtao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
             int nthreads) {
  const Constants k(in, s);
  // Texel indices are 32-bit.
  CV_Assert(int64_t(k.grid.width) * int64_t(k.grid.height) <= int64_t(INT32_MAX));
  Frame f{in, {}, {}, {}};
  build_texels(in, f.texels, f.planes, nthreads);
  if (const cv::Mat* back = back_layer(in, k)) build_texel_thickness(in, *back, f.texels, k.perspective, f.thickness, nthreads);
  // Tiles of kTileWidthPx x kTileHeightPx pixels: a pixel's taps land anywhere within its
  // radius, so the texels a tile reads are its footprint grown by the radius, which stays
  // in cache while the tile runs; row by row, the band of rows within the radius of a
  // whole row would not.
  parallel_rows(
      cv::Range(roi.y, roi.y + roi.height), nthreads,
      [&](const cv::Range& rows) {
        for (int y0 = rows.start; y0 < rows.end; y0 += kTileHeightPx) {
          const int y1 = std::min(y0 + kTileHeightPx, rows.end);
          for (int x0 = roi.x; x0 < roi.x + roi.width; x0 += kTileWidthPx)
            shade_tile(k, f, out, x0, std::min(x0 + kTileWidthPx, roi.x + roi.width), y0, y1);
        }
      },
      kTileHeightPx);
}

}  // namespace ssdo::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::detail {

SSDO_AO_METHOD_DISPATCH(ao_gtao)

}  // namespace ssdo::detail
#endif  // HWY_ONCE
