// Confidence: the observed fraction of the sampled neighbourhood (definition in
// confidence.h).
//
// Rays are parametrised by planar depth s: x(s) = o + s u with u.z = -1 (PixelRays,
// core/camera.h: affine in the pixel position, so one pixel's ray costs two multiply-adds). In s,
// the sphere |x(s) - p| = R is the quadratic (u.u) s^2 + 2 (u.f) s + (f.f - R^2) = 0 with
// f = o - p, the tangent plane n.(x(s) - p) = 0 is s* = -(n.f) / (n.u), and the stored
// surface at the tap is s = depth_view(tap). Lengths in s scale to lengths along the ray by
// |u|, which weights each chord by its true length.
#include "kernels/confidence.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/confidence.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include "kernels/settings_check.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "kernels/denoise.h"
#include "kernels/noise.h"
#include "core/parallel.h"
#include "core/uninitialized.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

// Golden angle, radians: successive Vogel-spiral taps (Vogel 1979, "A better way to
// construct the sunflower head") turn by it, which spreads N taps evenly over a disk for
// any N.
constexpr float kGoldenAngle = 2.39996322972865332f;

// ConfidenceSettings::taps' upper bound: a pixel's taps fit in fixed arrays.
constexpr int kMaxTaps = 256;

// kLanes foreground pixels of a row evaluated together, one per vector lane: every lane
// runs the same operations in the same order as a pixel alone (its sums in tap order), so
// the lanes change the speed, not the bits. Two AVX-512 registers of floats (four AVX2
// ones) rather than one: each loop then runs independent chains of operations, which keep
// the arithmetic units busy while one waits on a square root or a division (as GTAO's
// groups, kernels/ao_gtao.cpp); four AVX-512 registers measured no faster than two
// (docs/performance.md, "GTAO's groups of lanes").
constexpr int kLanes = 32;

struct PixelLanes {  // the per-pixel constants, one entry per lane
  alignas(64) float pxc[kLanes], pyc[kLanes];            // pixel centre
  alignas(64) float px[kLanes], py[kLanes], pz[kLanes];  // view-space point p
  alignas(64) float nx[kLanes], ny[kLanes], nz[kLanes];  // view-space normal n
  alignas(64) float rx_px[kLanes], ry_px[kLanes];        // projected radius, pixels
  alignas(64) float r2[kLanes];                          // radius^2, scene units^2
  alignas(64) float cos_r[kLanes], sin_r[kLanes];        // the pixel's spiral rotation
  // Perspective only, where every ray starts at o = 0: f = o - p, c = f.f - R^2 and n.f
  // are the pixel's, whatever the tap.
  alignas(64) float fx[kLanes], fy[kLanes], fz[kLanes], c[kLanes], nf[kLanes];
};

struct TapLanes {  // every tap of the lanes, [tap][lane]
  alignas(64) float x[kMaxTaps][kLanes], y[kMaxTaps][kLanes];  // tap pixel
  alignas(64) int index[kMaxTaps][kLanes];                      // into TapFrame::surface
  alignas(64) float s0[kMaxTaps][kLanes], s1[kMaxTaps][kLanes], len_scale[kMaxTaps][kLanes];
  alignas(64) float surface[kMaxTaps][kLanes];
};

// What the taps read, shared by every pixel of a call.
struct TapFrame {
  PixelRays rays;
  const float* spiral_x;
  const float* spiral_y;
  int n_taps;
  int width, height;
  // Per texel of the frame (row-major, contiguous): the largest ray parameter still in
  // front of the stored surface, 0 where the tap is unknown; one more unknown texel at
  // index width * height, for off-screen taps.
  const float* surface;
  // With other views (else null): their verdicts (asked where a tap is unknown), per texel
  // (indexed as surface) the bins of [surface, surface + view_bins x bin_depth] behind it
  // that they decide (bit i: bin i; decided_bins_behind_surfaces), and per tap where along
  // an unknown tap's chord they are asked, [0, 1).
  const PointVerdicts* verdicts;
  const float* chord_offsets;
  const uint8_t* decided_bins;
  int view_bins;
  float bin_depth;  // ray parameter units (planar depth)
};

// Pass 1 of sum_chords, every tap of every lane (no branch: 8 lanes per instruction): the
// tap pixel, and the chord [s0, s1] of the hemisphere along the ray through its centre
// (where its depth was sampled), in ray parameter units; len_scale converts them to
// lengths. Taps whose ray misses get s1 = s0.
template <bool kPerspective>
inline void hemisphere_chords(const TapFrame& frame, const PixelLanes& __restrict lane,
                              TapLanes& __restrict tap) {
  const PixelRays rays = frame.rays;
  for (int k = 0; k < frame.n_taps; ++k) {
    const float vx = frame.spiral_x[k], vy = frame.spiral_y[k];
#pragma GCC unroll 1
    for (int j = 0; j < kLanes; ++j) {
      const float cos_r = lane.cos_r[j], sin_r = lane.sin_r[j];
      const float tx = std::floor(lane.pxc[j] + lane.rx_px[j] * (cos_r * vx - sin_r * vy));
      const float ty = std::floor(lane.pyc[j] + lane.ry_px[j] * (sin_r * vx + cos_r * vy));
      const float cx = tx + 0.5f, cy = ty + 0.5f;
      const glm::vec3 n(lane.nx[j], lane.ny[j], lane.nz[j]);
      const glm::vec3 u = rays.u0 + cx * rays.ux + cy * rays.uy;
      glm::vec3 f;
      float c, nf;
      if constexpr (kPerspective) {
        f = glm::vec3(lane.fx[j], lane.fy[j], lane.fz[j]);
        c = lane.c[j];
        nf = lane.nf[j];
      } else {
        const glm::vec3 p(lane.px[j], lane.py[j], lane.pz[j]);
        const glm::vec3 o = rays.o0 + cx * rays.ox + cy * rays.oy;
        f = o - p;
        c = glm::dot(f, f) - lane.r2[j];
        nf = glm::dot(n, f);
      }
      const float a = glm::dot(u, u), b = glm::dot(u, f);
      const float disc = b * b - a * c;
      const float root = std::sqrt(std::max(disc, 0.0f));
      float s0 = std::max((-b - root) / a, 0.0f), s1 = (-b + root) / a;
      // Clip to the hemisphere n.(x - p) >= 0. A ray parallel to the tangent plane
      // (nu = 0) is kept whole above it and dropped below it.
      const float nu = glm::dot(n, u);
      const float s_plane = -nf / nu;
      s1 = nu < 0.0f ? std::min(s1, s_plane) : s1;
      s0 = nu > 0.0f ? std::max(s0, s_plane) : s0;
      const bool hit = disc > 0.0f && !(nu == 0.0f && nf < 0.0f) && s1 > s0;
      tap.x[k][j] = tx;
      tap.y[k][j] = ty;
      tap.s0[k][j] = s0;
      tap.s1[k][j] = hit ? s1 : s0;  // an empty chord: weighs nothing below
      tap.len_scale[k][j] = std::sqrt(a);
    }
  }
}

// Passes 2 and 3 of sum_chords: the texel of each tap (off-screen taps read the unknown
// texel; the clamp keeps the conversion defined, std::max(0, t) also maps NaN to 0), then
// the surface there (scattered reads, apart from the arithmetic).
inline void surface_at_taps(const TapFrame& frame, TapLanes& __restrict tap) {
  const int n_taps = frame.n_taps, width = frame.width;
  const float width_f = float(frame.width), height_f = float(frame.height);
  const float max_x = float(frame.width - 1), max_y = float(frame.height - 1);
  const int unknown_index = frame.width * frame.height;
  for (int k = 0; k < n_taps; ++k) {
#pragma GCC unroll 1
    for (int j = 0; j < kLanes; ++j) {
      const float tx = tap.x[k][j], ty = tap.y[k][j];
      const bool on_screen = (tx >= 0.0f) & (ty >= 0.0f) & (tx < width_f) & (ty < height_f);
      const int index = int(std::min(std::max(0.0f, ty), max_y)) * width +
                        int(std::min(std::max(0.0f, tx), max_x));
      tap.index[k][j] = on_screen ? index : unknown_index;
    }
  }
  for (int k = 0; k < n_taps; ++k)
    for (int j = 0; j < kLanes; ++j) tap.surface[k][j] = frame.surface[tap.index[k][j]];
}

// Pass 4 of sum_chords, in tap order per lane: the chord's length, and its observed part
// [s0, min(s1, s_surface)] where the tap is known. Taps adding nothing add +0.0, which
// leaves the (non-negative) sums unchanged: the same sums as skipping them.
inline void add_chords(int n_taps, const TapLanes& __restrict tap, double (&observed)[kLanes],
                       double (&total)[kLanes]) {
  for (int j = 0; j < kLanes; ++j) observed[j] = total[j] = 0.0;
  for (int k = 0; k < n_taps; ++k) {
#pragma GCC unroll 1
    for (int j = 0; j < kLanes; ++j) {
      const float s0 = tap.s0[k][j], s1 = tap.s1[k][j], len_scale = tap.len_scale[k][j];
      const float s_surface = tap.surface[k][j];
      const bool chord = s1 > s0;
      const float seen = std::min(s1, s_surface) - s0;
      const bool seen_tap = chord & (s_surface > 0.0f) & (seen > 0.0f);
      total[j] += double(chord ? (s1 - s0) * len_scale : 0.0f);
      observed[j] += double(seen_tap ? seen * len_scale : 0.0f);
    }
  }
}

// Where a tap is unknown to this frame (off-screen, masked), every kUnknownTapStride-th of a
// pixel's unknown taps asks the views, and the decided fraction of their chords stands for
// all its unknown chords. Unknown taps come in regions (past the frame's edge, over the
// sky) that the views see alike, so the fraction varies little among them; asking a
// quarter of them costs a quarter.
constexpr int kUnknownTapStride = 4;

// The part of the known taps' chords hidden behind their surfaces that the views decide,
// times len_scale, summed per lane in tap order (no branch: a vector of lanes per
// instruction). Tap k's hidden part [begin, s1], begin = max(s0, s_surface), overlaps the
// bins of its texel from the one holding begin to the one holding s1; each bin the views
// decide (its bit in TapFrame::decided_bins) adds its overlap. A chord through the
// neighbourhood is at most 2 radii long and |u| >= 1, so the bins' 2 radii of planar depth
// behind a tap's surface hold every hidden part of its chords. Taps that are unknown or
// hide nothing add +0.0, which leaves the sums as skipping them would.
void add_decided_behind_surfaces(const TapFrame& frame, const TapLanes& __restrict tap,
                                 float (&behind_surface)[kLanes]) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::CappedTag<float, kLanes> d;  // a pixel per lane, at most kLanes
  const hn::RebindToSigned<decltype(d)> di;
  const size_t n = hn::Lanes(d);
  const auto zero = hn::Zero(d), w = hn::Set(d, frame.bin_depth);
  const auto bins = hn::Set(d, float(frame.view_bins)), last_bin = hn::Set(d, float(frame.view_bins) - 1.0f);
  alignas(64) int32_t bits[kLanes];
  for (size_t j0 = 0; j0 < size_t(kLanes); j0 += n) {
    auto sum = zero;
    for (int k = 0; k < frame.n_taps; ++k) {
      const auto s_surface = hn::Load(d, &tap.surface[k][j0]), s1_tap = hn::Load(d, &tap.s1[k][j0]);
      const auto begin_tap = hn::Max(hn::Load(d, &tap.s0[k][j0]), s_surface);
      const auto counted = hn::And(hn::Gt(s_surface, zero), hn::Gt(s1_tap, begin_tap));  // false on NaN
      if (hn::AllFalse(d, counted)) continue;
      // Uncounted lanes take an empty part at 0 (keeps the conversions below defined).
      const auto surface = hn::IfThenElseZero(counted, s_surface);
      const auto begin = hn::IfThenElseZero(counted, begin_tap), s1 = hn::IfThenElseZero(counted, s1_tap);
      const auto first = hn::ConvertTo(di, hn::Min(hn::Div(hn::Sub(begin, surface), w), bins));
      const auto last = hn::ConvertTo(di, hn::Min(hn::Div(hn::Sub(s1, surface), w), last_bin));
      for (size_t j = 0; j < n; ++j) bits[j] = frame.decided_bins[tap.index[k][j0 + j]];
      const auto tap_bits = hn::Load(di, bits);
      auto decided = zero;
      for (int i = 0; i < frame.view_bins; ++i) {
        const auto lo = hn::Add(surface, hn::Set(d, float(i) * frame.bin_depth));
        const auto overlap = hn::Sub(hn::Min(hn::Add(lo, w), s1), hn::Max(lo, begin));
        const auto bin = hn::Set(di, i);
        const auto outside_part = hn::RebindMask(d, hn::Or(hn::Gt(first, bin), hn::Gt(bin, last)));
        const auto bit_set =
            hn::RebindMask(d, hn::Ne(hn::And(hn::ShiftRightSame(tap_bits, i), hn::Set(di, 1)), hn::Zero(di)));
        const auto adds = hn::AndNot(outside_part, hn::And(hn::And(counted, hn::Gt(overlap, zero)), bit_set));
        decided = hn::Add(decided, hn::IfThenElseZero(adds, overlap));
      }
      // len_scale may be NaN where nothing is counted.
      sum = hn::Add(sum, hn::IfThenElseZero(counted, hn::Mul(decided, hn::Load(d, &tap.len_scale[k][j0]))));
    }
    hn::Store(sum, d, &behind_surface[j0]);
  }
}

// The unknown chords of the lanes (taps off-screen or on masked texels: surface 0) and the
// views' verdicts on them: every kUnknownTapStride-th unknown tap of a lane asks the views
// at one point of its chord, offset along it per tap by the golden-ratio sequence (the taps
// of a pixel spread their points evenly over the chords), and the decided fraction of the
// asked chords stands for all the lane's unknown chords. Per lane, in tap order: the
// unknown chords' length, the asked chords' length, and the decided ones'.
void add_unknown_chords_decided(const TapFrame& frame, const TapLanes& __restrict tap, float (&unknown)[kLanes],
                                float (&unknown_asked)[kLanes], float (&unknown_decided)[kLanes]) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::CappedTag<float, kLanes> d;  // a pixel per lane, at most kLanes
  const hn::RebindToSigned<decltype(d)> di;
  const size_t n = hn::Lanes(d);
  // The asks of every lane in tap order (so each lane's in its own order), asked at once.
  constexpr int kMaxAsks = kLanes * (kMaxTaps / kUnknownTapStride);
  glm::vec3 points[kMaxAsks];
  float asked_length[kMaxAsks];
  uint8_t asked_lane[kMaxAsks], decided[kMaxAsks];
  int n_asks = 0;
  alignas(64) float length_of[kLanes];
  for (size_t j0 = 0; j0 < size_t(kLanes); j0 += n) {
    auto unknown_sum = hn::Zero(d), asked_sum = hn::Zero(d);
    auto n_unknown = hn::Zero(di);
    for (int k = 0; k < frame.n_taps; ++k) {
      const auto s0 = hn::Load(d, &tap.s0[k][j0]), s1 = hn::Load(d, &tap.s1[k][j0]);
      // Unknown (surface 0) and with a chord (false on empty chords and NaN).
      const auto is_unknown = hn::And(hn::Le(hn::Load(d, &tap.surface[k][j0]), hn::Zero(d)), hn::Gt(s1, s0));
      if (hn::AllFalse(d, is_unknown)) continue;
      const auto length = hn::IfThenElseZero(is_unknown, hn::Mul(hn::Sub(s1, s0), hn::Load(d, &tap.len_scale[k][j0])));
      unknown_sum = hn::Add(unknown_sum, length);
      const auto is_unknown_i = hn::RebindMask(di, is_unknown);
      const auto asks = hn::RebindMask(
          d, hn::And(is_unknown_i, hn::Eq(hn::And(n_unknown, hn::Set(di, kUnknownTapStride - 1)), hn::Zero(di))));
      n_unknown = hn::Add(n_unknown, hn::IfThenElseZero(is_unknown_i, hn::Set(di, 1)));
      asked_sum = hn::Add(asked_sum, hn::IfThenElseZero(asks, length));
      if (hn::AllFalse(d, asks)) continue;
      hn::Store(length, d, length_of);
      uint8_t ask_bits[8] = {};
      hn::StoreMaskBits(d, asks, ask_bits);
      for (size_t j = 0; j < n; ++j) {
        if (!((ask_bits[j / 8] >> (j % 8)) & 1u)) continue;
        const size_t lane = j0 + j;
        const float a = tap.s0[k][lane], b = tap.s1[k][lane];
        const float t = a + frame.chord_offsets[k] * (b - a);
        points[n_asks] = frame.rays.point(tap.x[k][lane] + 0.5f, tap.y[k][lane] + 0.5f, t);
        asked_length[n_asks] = length_of[j];
        asked_lane[n_asks++] = uint8_t(lane);
      }
    }
    hn::Store(unknown_sum, d, unknown + j0);
    hn::Store(asked_sum, d, unknown_asked + j0);
  }
  frame.verdicts->decided({points, size_t(n_asks)}, {decided, size_t(n_asks)});
  for (int j = 0; j < kLanes; ++j) unknown_decided[j] = 0.0f;
  for (int a = 0; a < n_asks; ++a)
    if (decided[a]) unknown_decided[asked_lane[a]] += asked_length[a];
}

// Pass 5 of sum_chords, with views only: the part of each tap's chord this frame does not
// see, as far as the other views decide it, added to the observed sums: behind the known
// taps' surfaces (add_decided_behind_surfaces) and along the unknown taps' chords
// (add_unknown_chords_decided).
void add_observed_by_views(const TapFrame& frame, const TapLanes& tap, double (&observed)[kLanes]) {
  alignas(64) float behind_surface[kLanes], unknown[kLanes], unknown_asked[kLanes], unknown_decided[kLanes];
  add_decided_behind_surfaces(frame, tap, behind_surface);
  add_unknown_chords_decided(frame, tap, unknown, unknown_asked, unknown_decided);
  for (int j = 0; j < kLanes; ++j) {
    const float unknown_observed =
        unknown_asked[j] > 0.0f ? unknown[j] * (unknown_decided[j] / unknown_asked[j]) : 0.0f;
    observed[j] += double(behind_surface[j] + unknown_observed);
  }
}

// The sums of the confidence's ratio (confidence.h) of the pixels in the lanes.
// kPerspective: the rays start at o = o0 + cx ox + cy oy = +0 exactly (o0, ox, oy are +0,
// so each product is +-0 and the sums +0) for every tap with a finite centre, and f, c and
// n.f are the pixel's (PixelLanes). The other centres are NaN (a NaN projected radius, as
// where pixels_per_unit is infinite), which makes u, a and s0 NaN and the chord empty
// either way.
template <bool kPerspective>
void sum_chords(const TapFrame& frame, const PixelLanes& __restrict lane,
                TapLanes& __restrict tap, double (&observed)[kLanes], double (&total)[kLanes]) {
  hemisphere_chords<kPerspective>(frame, lane, tap);
  surface_at_taps(frame, tap);
  add_chords(frame.n_taps, tap, observed, total);
  if (frame.verdicts != nullptr) add_observed_by_views(frame, tap, observed);
}

// The unrotated Vogel spiral: equal-area rings (rho = sqrt((k + 0.5) / N)), golden-angle
// turns. Each pixel rotates it by its own angle (a 2x2 rotation per tap, not a sincos).
struct Spiral {
  std::vector<float> x, y;
};

Spiral vogel_spiral(int n_taps) {
  Spiral spiral{std::vector<float>(size_t(n_taps)), std::vector<float>(size_t(n_taps))};
  for (int k = 0; k < n_taps; ++k) {
    const float rho = std::sqrt((float(k) + 0.5f) / float(n_taps));
    const float angle = float(k) * kGoldenAngle;
    spiral.x[size_t(k)] = rho * std::cos(angle);
    spiral.y[size_t(k)] = rho * std::sin(angle);
  }
  return spiral;
}

// Tap validity and surface in one plane, read once per tap: depth_view x (1 +
// depth_bias_relative) (the largest ray parameter still in front of the stored surface,
// within the relative bias: the pixel's own plane seen at a tap is observed) where the tap
// is known, 0 where it is masked or its depth is not a positive finite value. Contiguous
// rows, so a tap is one index, and one more unknown texel past the frame's end for
// off-screen taps. The whole frame: taps reach anywhere, whatever the roi.
UninitializedVector<float> surface_plane(const cv::Mat& depth_view, const cv::Mat& mask,
                                         float depth_bias_relative, int nthreads) {
  const int width = depth_view.cols, height = depth_view.rows;
  const float bias_scale = 1.0f + depth_bias_relative;
  const size_t n_texels = size_t(width) * size_t(height);
  UninitializedVector<float> surface(n_texels + 1);  // every texel is written below
  surface[n_texels] = 0.0f;
  parallel_rows(cv::Range(0, height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = mask.ptr<uint8_t>(y);
      const float* depth_row = depth_view.ptr<float>(y);
      float* surface_row = surface.data() + size_t(y) * size_t(width);
      for (int x = 0; x < width; ++x) {
        const float d = depth_row[x];
        const bool known = mask_row[x] != 0 && d > 0.0f && std::isfinite(d);
        surface_row[x] = known ? d * bias_scale : 0.0f;
      }
    }
  });
  return surface;
}

// What the pixels of a call read besides their taps.
struct PixelFrame {
  const cv::Mat& depth_view;
  const cv::Mat& normal_view;
  const cv::Mat& mask;
  const Camera& camera;
  const ConfidenceSettings& settings;
  const TapFrame& taps;
  bool perspective;  // camera.is_perspective()
  cv::Point frame_origin_px;  // compute_confidence's: the rotation is the picture pixel's
};

// The foreground pixels waiting for a full set of lanes; lanes fill across the rows of a
// strip.
struct PendingPixels {
  int x[kLanes], y[kLanes];
  float* out[kLanes];
  int n = 0;
};

// The per-pixel constants of the pending pixels: centre, view-space point and normal, the
// projected radius, the spiral's rotation and, for perspective rays, f = o - p, c and n.f.
void set_up_lanes(const PixelFrame& frame, const PendingPixels& pending, PixelLanes& lane) {
  const ConfidenceSettings& s = frame.settings;
  const PixelRays& rays = frame.taps.rays;
  alignas(64) float depth[kLanes], rotation_turns[kLanes], ppu_x[kLanes], ppu_y[kLanes];
  for (int j = 0; j < kLanes; ++j) {
    const int x = pending.x[j], y = pending.y[j];
    depth[j] = frame.depth_view.ptr<float>(y)[x];
    const cv::Vec3f& n = frame.normal_view.ptr<cv::Vec3f>(y)[x];
    lane.nx[j] = n[0], lane.ny[j] = n[1], lane.nz[j] = n[2];
    lane.pxc[j] = float(x) + 0.5f, lane.pyc[j] = float(y) + 0.5f;
    rotation_turns[j] = noise01(x - frame.frame_origin_px.x, y - frame.frame_origin_px.y, 0, s.seed);
  }
  for (int j = 0; j < kLanes; ++j) {
    const glm::vec2 ppu = frame.camera.pixels_per_unit(depth[j]);
    ppu_x[j] = ppu.x, ppu_y[j] = ppu.y;
    sincos_turns(rotation_turns[j], lane.cos_r[j], lane.sin_r[j]);
  }
  for (int j = 0; j < kLanes; ++j) {
    const float d = depth[j], pxc = lane.pxc[j], pyc = lane.pyc[j];
    const glm::vec3 p = rays.point(pxc, pyc, d);
    // The estimator's neighbourhood: the radius, shrunk where its projection exceeds
    // max_radius_px (the methods shrink theirs the same way).
    float radius = s.radius_world;
    const float radius_px_max = radius * std::max(ppu_x[j], ppu_y[j]);
    radius = radius_px_max > s.max_radius_px ? radius * (s.max_radius_px / radius_px_max)
                                             : radius;
    lane.px[j] = p.x, lane.py[j] = p.y, lane.pz[j] = p.z;
    lane.rx_px[j] = radius * ppu_x[j], lane.ry_px[j] = radius * ppu_y[j];
    lane.r2[j] = radius * radius;
    const glm::vec3 f = glm::vec3(0.0f) - p;  // o - p with the perspective o = 0
    const glm::vec3 n(lane.nx[j], lane.ny[j], lane.nz[j]);
    lane.fx[j] = f.x, lane.fy[j] = f.y, lane.fz[j] = f.z;
    lane.c[j] = glm::dot(f, f) - lane.r2[j];
    lane.nf[j] = glm::dot(n, f);
  }
}

// The confidence of the pending pixels (unfilled lanes repeat the last pixel and are not
// written); empties the pending set.
void evaluate_pending(const PixelFrame& frame, PendingPixels& pending, PixelLanes& lane, TapLanes& tap) {
  for (int j = pending.n; j < kLanes; ++j) {
    pending.x[j] = pending.x[pending.n - 1], pending.y[j] = pending.y[pending.n - 1];
  }
  set_up_lanes(frame, pending, lane);
  double observed[kLanes], total[kLanes];
  if (frame.perspective)
    sum_chords<true>(frame.taps, lane, tap, observed, total);
  else
    sum_chords<false>(frame.taps, lane, tap, observed, total);
  for (int j = 0; j < pending.n; ++j)
    *pending.out[j] = total[j] > 0.0 ? float(std::clamp(observed[j] / total[j], 0.0, 1.0)) : 1.0f;
  pending.n = 0;
}

// The confidence of rows [rows.start, rows.end), columns of r: 1 on background, the
// observed fraction on foreground pixels, evaluated kLanes at a time.
void confidence_rows(const PixelFrame& frame, const cv::Range& rows, const cv::Rect& r, cv::Mat& confidence) {
  PixelLanes lane;
  TapLanes tap;
  PendingPixels pending;
  // Foreground pixels are found a chunk of a row at a time, without a branch per pixel.
  constexpr int kChunk = 64;
  int chunk_x[kChunk];
  for (int y = rows.start; y < rows.end; ++y) {
    const uint8_t* mask_row = frame.mask.ptr<uint8_t>(y);
    const float* depth_row = frame.depth_view.ptr<float>(y);
    float* out = confidence.ptr<float>(y);
    for (int x0 = r.x; x0 < r.x + r.width; x0 += kChunk) {
      const int x1 = std::min(x0 + kChunk, r.x + r.width);
      int n_foreground = 0;
      for (int x = x0; x < x1; ++x) {
        const float d = depth_row[x];
        const bool foreground = (mask_row[x] != 0) & (d > 0.0f) & std::isfinite(d);
        out[x] = 1.0f;  // background; foreground pixels are overwritten when evaluated
        chunk_x[n_foreground] = x;
        n_foreground += foreground;
      }
      for (int i = 0; i < n_foreground; ++i) {
        pending.x[pending.n] = chunk_x[i], pending.y[pending.n] = y;
        pending.out[pending.n] = out + chunk_x[i];
        if (++pending.n == kLanes) evaluate_pending(frame, pending, lane, tap);
      }
    }
  }
  if (pending.n > 0) evaluate_pending(frame, pending, lane, tap);
}

}  // namespace

void compute_confidence(const cv::Mat& depth_view, const cv::Mat& normal_view,
                        const cv::Mat& mask, const Camera& camera,
                        const ConfidenceSettings& s, cv::Mat& confidence, cv::Rect roi,
                        int nthreads, const ConfidenceViews& views, cv::Point frame_origin_px) {
  CV_Assert(ssdo::validate(s).empty());
  CV_Assert(depth_view.type() == CV_32FC1);
  const cv::Size size = depth_view.size();
  CV_Assert(normal_view.type() == CV_32FC3 && normal_view.size() == size);
  CV_Assert(mask.type() == CV_8UC1 && mask.size() == size);
  CV_Assert(camera.width_px == size.width && camera.height_px == size.height);
  if (confidence.size() != size || confidence.type() != CV_32FC1)
    confidence.create(size, CV_32FC1);
  const cv::Rect r = resolve_roi(roi, size);
  if (r.empty()) return;
  // The smoothing reads the fraction up to its radius around r: computed there first, into
  // an image of its own (zero elsewhere: nothing undefined reaches the blur's planes).
  const bool smoothed = s.smoothing_radius_px > 0;
  const cv::Rect raw_r = denoise_reads(r, smoothing(s), size);
  cv::Mat raw = smoothed ? cv::Mat::zeros(size, CV_32FC1) : confidence;
  const Spiral spiral = vogel_spiral(s.taps);
  const UninitializedVector<float> surface = surface_plane(depth_view, mask, s.depth_bias_relative, nthreads);
  std::unique_ptr<PointVerdicts> verdicts;
  if (!views.views.empty()) verdicts = std::make_unique<PointVerdicts>(camera, views.views, views.settings);
  TapFrame taps{pixel_rays(camera), spiral.x.data(), spiral.y.data(), s.taps, size.width, size.height, surface.data(),
                verdicts.get(), nullptr, nullptr, s.view_bins, 2.0f * s.radius_world / float(s.view_bins)};
  cv::Mat decided_bins;  // contiguous: created whole
  std::vector<float> chord_offsets;
  if (verdicts) {
    decided_bins = decided_bins_behind_surfaces({depth_view, mask, camera}, views.views, views.settings,
                                                1.0f + s.depth_bias_relative, taps.bin_depth, s.view_bins, nthreads);
    taps.decided_bins = decided_bins.ptr<uint8_t>();
    // The golden-ratio sequence: the taps of a pixel spread their points evenly over [0, 1).
    for (int k = 0; k < s.taps; ++k) chord_offsets.push_back(std::fmod(0.5f + 0.6180339887f * float(k), 1.0f));
    taps.chord_offsets = chord_offsets.data();
  }
  const PixelFrame frame{depth_view, normal_view, mask, camera, s, taps, camera.is_perspective(), frame_origin_px};
  parallel_rows(cv::Range(raw_r.y, raw_r.y + raw_r.height), nthreads,
                [&](const cv::Range& rows) { confidence_rows(frame, rows, raw_r, raw); });
  if (smoothed) denoise_bilateral(raw, depth_view, normal_view, mask, smoothing(s), confidence, r, nthreads);
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

DenoiseSettings smoothing(const ConfidenceSettings& s) {
  DenoiseSettings d;
  d.radius_px = s.smoothing_radius_px;
  d.sigma_px = 0.75f * float(s.smoothing_radius_px);
  return d;
}

// Settings, not pixels: compiled once, outside the per-target code.
bool runs_on_half_grid(const ConfidenceSettings& s) { return s.resolution_divisor == 2; }

std::string validate(const ConfidenceSettings& s) {
  if (std::string e = detail::check_radius(s.radius_world, s.max_radius_px); !e.empty()) return e;
  if (s.taps < 4 || s.taps > HWY_NAMESPACE::kMaxTaps) return detail::out_of_range("taps", s.taps, "[4, 256]");
  if (!(s.depth_bias_relative >= 0.0f && s.depth_bias_relative <= 0.1f))
    return detail::out_of_range("depth_bias_relative", s.depth_bias_relative, "[0, 0.1]");
  if (s.smoothing_radius_px < 0 || s.smoothing_radius_px > 8)
    return detail::out_of_range("smoothing_radius_px", s.smoothing_radius_px, "[0, 8]");
  if (s.view_bins < 1 || s.view_bins > 8) return detail::out_of_range("view_bins", s.view_bins, "[1, 8]");
  if (s.resolution_divisor < 1 || s.resolution_divisor > 2)
    return detail::out_of_range("resolution_divisor", s.resolution_divisor, "[1, 2]");
  return {};
}

HWY_EXPORT(compute_confidence);
void compute_confidence(const cv::Mat& depth_view, const cv::Mat& normal_view, const cv::Mat& mask,
                        const Camera& camera, const ConfidenceSettings& settings, cv::Mat& confidence, cv::Rect roi,
                        int nthreads, const ConfidenceViews& views, cv::Point frame_origin_px) {
  HWY_DYNAMIC_DISPATCH(compute_confidence)(depth_view, normal_view, mask, camera, settings, confidence, roi, nthreads,
                                           views, frame_origin_px);
}

}  // namespace ssdo
#endif  // HWY_ONCE
