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
//   & Gilet 2023, "Screen Space Indirect Lighting with Visibility Bitmask"). The sectors
//   are fixed angles from the projected normal, equally spaced in the pseudo-angle
//   p = sin f / (|sin f| + cos f) of the angle f = h - n (p in [-1, 1] over the
//   hemisphere), which a tap's end gets from its slice coordinates with one division and
//   no arccosine; each sector's measure is closed-form in n (see SectorTables), and the
//   visible part of a slice is its analytic integral less its occupied sectors' measure.
//   This lets light through the gap under a floating object, which a height field cannot.
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
// Pooled slices (AoSettings::pool_slices), for one slice per pixel: one slice's ratio is
// noisy and biased (its expectation is the mean ratio, not the ratio of the means; a pixel
// on a crease line reads 0.58 for 0.5). A slice's open measure averages 1 over slice angles
// uniform about the view vector (GTAO eq. 10's normalisation: |pn| (cos n + n sin n)
// integrates the cosine lobe over the hemisphere), so for any R, R + (v - R o) / slices
// has the expectation of v / slices (one slice's visible measure), the AO: a control
// variate (Owen 2013, "Monte Carlo theory, methods and examples", ch. 8). R is the ratio of
// the sums of the 3x3 texels on the pixel's surface (pooled_sums): near the pixel's own
// AO, it leaves little of v's change with the slice angle. An open neighbourhood gives
// R = 1 and v = o: exactly 1. The screen's slice angles are uniform about the view vector only on the axis; off it the
// open measure's mean departs from 1 slightly, and R's error with it.
//
// Bent normal: the cosine-weighted mean visible direction of each slice between its
// height-field horizons (closed-form integrals of cos(t - n)|sin t| (cos t, sin t)),
// summed over slices and normalised.
//
// The code follows the passes (as XeGTAO's): the settings become Constants once; the frame
// becomes packed texels and their coarser levels for the far taps (build_texels,
// build_coarse_levels); tiles of pixels are shaded row by row, each row planned first
// across its pixels (plan_row: tap patterns and points); then groups of kLanes pixels, one
// per vector lane (shade_group), slice by slice (the slice's frame in the lanes,
// SliceLanes::compute; shade_slice), each slice's taps a step at a time for every lane
// (group_step_indices, gather_texels, step_coordinates), with either the height-field
// horizons (height_field_step) and their integral (height_field_integral), or the occluder
// segments (step_intervals), the visibility mask's ordered pass (visibility_mask_step) and
// its integral (visibility_mask_integrals); the slice's bent normal
// (add_slice_bent_normal); a row's sums become AO and bent normal in finish_row.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/ao_gtao.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <numbers>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/iota_lanes.h"
#include "kernels/noise.h"
#include "kernels/record_lanes.h"
#include "core/parallel.h"
#include "core/uninitialized.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::detail::HWY_NAMESPACE {
namespace {

constexpr int kSectors = 64;

// Tiles the pixels are shaded in, pixels (see shade_tile). 64 wide: a row is one to four
// groups of lanes (kLanes), whose taps stay in cache across the tile's rows; 32 tall: the
// strips of the parallel loop, whose count balances the threads.
constexpr int kTileWidthPx = 64;
constexpr int kTileHeightPx = 32;


// occupied[l] |= the run of count[l] sectors from k0[l], for kLanes lanes (64-bit lanes
// with per-lane shifts: GCC does not vectorise a constant shifted by a vector).
inline void add_sector_runs(const int32_t* k0, const int32_t* count, uint64_t* occupied, size_t lanes) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::ScalableTag<uint64_t> du;
  const hn::RebindToSigned<decltype(du)> di;
  const hn::Rebind<int32_t, decltype(di)> d32;
  const auto one = hn::Set(du, 1), all = hn::Set(du, ~uint64_t(0));
  for (size_t l = 0; l < lanes; l += hn::Lanes(du)) {
    const auto n32 = hn::LoadU(d32, count + l);
    const auto whole = hn::RebindMask(du, hn::Gt(hn::PromoteTo(di, n32), hn::Set(di, kSectors - 1)));
    // A shift by 64 is undefined (and 0 or 1 depending on the instruction set): whole runs
    // take the select, their shift is clamped.
    const auto n = hn::PromoteTo(di, hn::Min(n32, hn::Set(d32, kSectors - 1)));
    const auto run = hn::IfThenElse(whole, all, hn::Sub(hn::Shl(one, hn::BitCast(du, n)), one));
    const auto shift = hn::BitCast(du, hn::PromoteTo(di, hn::LoadU(d32, k0 + l)));
    hn::StoreU(hn::Or(hn::LoadU(du, occupied + l), hn::Shl(run, shift)), du, occupied + l);
  }
}

// c from c |c|.
inline float signed_sqrt(float x) { return std::copysign(std::sqrt(std::abs(x)), x); }

// The position of a direction in the visibility mask, u in [0, 1] (sector k covers
// [k, k + 1] / 64): u = (p + 1) / 2 of the pseudo-angle p = sin f / (|sin f| + cos f) of its
// angle f from the projected normal (-1 and 1 at the tangent limits, 0 along the normal; as
// tan f / (1 + |tan f|), monotone in f, its sectors between 1.8 and 3.6 degrees wide). From
// a point (v, d) of the slice plane (coordinates along the view vector and the slice
// direction) and the normal's angle n: sin f and cos f are d cos n - v sin n and
// v cos n + d sin n over the point's distance, which the ratio cancels. A point below the
// tangent line (cos f <= 0) is at the limit of its side `side_u` (1: +, 0: -).
inline float sector_u(float v, float d, float cos_n, float sin_n, float side_u) {
  const float a = d * cos_n - v * sin_n;
  const float b = v * cos_n + d * sin_n;
  return b > 0.0f ? 0.5f + 0.5f * (a / (std::abs(a) + b)) : side_u;
}

// The sectors' measures in the slice's cosine-weighted measure cos(f)|sin(f + n)| df
// (GTAO eq. 10's integrand with h = f + n). Where sin(f + n) >= 0 its antiderivative is
// cos n G1(f) + sin n G2(f) with G1 = sin^2 f / 2 and G2 = f / 2 + sin 2f / 4, so a run of
// sectors on one side of the view vector (f = -n) weighs cos n dG1 + sin n dG2 (negated
// below it), and the sums of dG1 and dG2 over any set of sectors come from a table per
// byte of the mask. Built once, in double, rounded to float.
struct SectorTables {
  float g1[kSectors + 1], g2[kSectors + 1];  // G1, G2 at the sectors' edges
  // dG1 and dG2 summed over the set bits of byte b of a mask with value v, at 256 b + v:
  // the two floats in one 64-bit entry (dG1 first in memory), one gather per byte.
  uint64_t byte_g[8 * 256];

  SectorTables() {
    double gd[kSectors + 1][2];
    for (int k = 0; k <= kSectors; ++k) {
      const double p = -1.0 + 2.0 * double(k) / kSectors;
      // tan f = p / (1 - |p|); the limits are +-pi / 2.
      const double f =
          std::abs(p) == 1.0 ? std::copysign(std::numbers::pi / 2.0, p) : std::atan(p / (1.0 - std::abs(p)));
      gd[k][0] = 0.5 * std::sin(f) * std::sin(f);
      gd[k][1] = 0.5 * f + 0.25 * std::sin(2.0 * f);
      g1[k] = float(gd[k][0]), g2[k] = float(gd[k][1]);
    }
    for (int b = 0; b < 8; ++b)
      for (int v = 0; v < 256; ++v) {
        float sum[2] = {0.0f, 0.0f};
        for (int j = 0; j < 8; ++j)
          if (v >> j & 1)
            for (int c = 0; c < 2; ++c) sum[c] += float(gd[8 * b + j + 1][c] - gd[8 * b + j][c]);
        std::memcpy(&byte_g[256 * b + v], sum, sizeof(sum));
      }
  }
};

const SectorTables& sector_tables() {
  static const SectorTables tables;
  return tables;
}

// What a tap reads from the pixel it lands in, in two planes: the view-space position p
// (planar depth -z) and the extent of its occluder segment (negative on masked pixels: no
// occluder there) in 16 bytes (one load, four texels per cache line), read by every tap;
// the normal and its tangent plane, read only by the connection rule's coplanar test. Taps
// land anywhere within the radius, so the bytes per tap set how much of the frame stays in
// cache. The segment runs from p away from the eye along its view ray for the occluder's
// thickness: in perspective p (1 + s), s in [0, extent], extent = thickness along the ray /
// |p| (from a second depth layer (back - front) / front in planar depth, the same ratio);
// through an orthographic camera p + t r, t in [0, extent], extent the thickness itself.
// Once per texel, so that a tap reads its segment with its position (no second plane, no
// square root and division per tap).
struct Texel {
  float x, y, z, extent;
};
struct TexelPlane {
  float nx, ny, nz, plane_c;  // unit normal and its tangent plane dot(n, x) = plane_c
};

// Coarser levels of the texels the far taps read (XeGTAO's depth MIP chain): level L holds
// one texel of each block of 2^L x 2^L texels, so that a tile's far taps read a footprint
// 4^L times smaller. A level's texel is a point sample, its block's centre texel: an average
// of a depth edge's two sides would be a point on neither surface, and the block's nearest
// texel would widen every near object by up to a block (occlusion that is not there). A
// tap reads level L from 2^(L + kFineTapsLog2) texels away, its texel then within 1/8 of its
// distance from where the pattern put it, and only where its pattern's steps are at least
// two blocks apart (level_cap), so that consecutive taps keep their order.
constexpr int kCoarseLevels = 4;
constexpr int kFineTapsLog2 = 3;  // taps within 8 texels read level 0

// The grid the taps land on, its levels, and the pattern's counts.
struct TapGrid {
  int width, height;
  int slices, steps;
  // The blocks are aligned to the picture's pixel (0, 0), at `origin` in the grid (a guard
  // band round the picture leaves the picture's blocks as they are): grid texel (x, y) is
  // in block ((x - origin.x) >> L, (y - origin.y) >> L) of level L. Level L's blocks from
  // block_x0[L], block_y0[L] (those of texel (0, 0)), level_width[L] x level_height[L] of
  // them, are stored from index level_base[L] of the texel arrays (level 0's from 0: texel
  // (x, y) at y width + x).
  cv::Point origin;
  int block_x0[kCoarseLevels + 1], block_y0[kCoarseLevels + 1];
  int level_width[kCoarseLevels + 1], level_height[kCoarseLevels + 1], level_base[kCoarseLevels + 1];
  int64_t texels;  // all levels' (indices are 32-bit: ao_gtao checks that they fit)

  TapGrid(int width_px, int height_px, cv::Point origin_px, int slice_count, int step_count)
      : width(width_px), height(height_px), slices(slice_count), steps(step_count), origin(origin_px) {
    int64_t base = 0;
    for (int level = 0; level <= kCoarseLevels; ++level) {
      block_x0[level] = -origin.x >> level;
      block_y0[level] = -origin.y >> level;
      level_width[level] = ((width - 1 - origin.x) >> level) - block_x0[level] + 1;
      level_height[level] = ((height - 1 - origin.y) >> level) - block_y0[level] + 1;
      level_base[level] = int(std::min<int64_t>(base, INT32_MAX));
      base += int64_t(level_width[level]) * int64_t(level_height[level]);
    }
    texels = base;
  }
};

// The coarsest level a pixel's taps read, their steps spacing_px apart: a block at most half
// the spacing (the largest L with spacing_px >= 2^(L + 1)), so that consecutive taps keep
// their order. floor_log2 (kernels/iota_lanes.h) is negative for a spacing of 0, which
// reaches no coarse level; step_indices reads the same bits in lanes (floor_log2_lanes).
inline int32_t level_cap(float spacing_px) {
  return std::clamp(ssdo::HWY_NAMESPACE::floor_log2(spacing_px) - 1, 0, kCoarseLevels);
}

// A tap's texel index in its level: index = offset[L] + (y' >> L) width[L] + (x' >> L) with
// x' = x - origin.x, y' = y - origin.y (the picture's pixel (0, 0) at 0).
struct LevelSelect {
  // The levels' entries, then zeros to a whole vector of 32-bit lanes: a vector with as
  // many lanes as levels looks them up by a permutation (step_indices).
  static constexpr int kEntries = std::max(kCoarseLevels + 1, int(HWY_MAX_BYTES / sizeof(int32_t)));
  cv::Point origin;
  alignas(HWY_MAX_BYTES) int32_t offset[kEntries] = {};
  alignas(HWY_MAX_BYTES) int32_t width[kEntries] = {};

  explicit LevelSelect(const TapGrid& g) : origin(g.origin) {
    for (int l = 0; l <= kCoarseLevels; ++l) {
      offset[l] = g.level_base[l] - g.block_y0[l] * g.level_width[l] - g.block_x0[l];
      width[l] = g.level_width[l];
    }
  }
};

// Each array's texels of levels 1 .. kCoarseLevels (from level_base[1]) from its level 0:
// block (bx, by) of level L holds its centre texel (right of and below the centre; clamped
// to the grid). One parallel loop over all the levels' rows: each reads level 0 only.
template <class... Record>
void build_coarse_levels(const TapGrid& g, int nthreads, Record*... records) {
  int rows = 0;
  for (int level = 1; level <= kCoarseLevels; ++level) rows += g.level_height[level];
  parallel_rows(cv::Range(0, rows), nthreads, [&](const cv::Range& r) {
    for (int row = r.start; row < r.end; ++row) {
      int level = 1, j = row;
      while (j >= g.level_height[level]) j -= g.level_height[level++];
      const int w = g.level_width[level], half = 1 << (level - 1);
      const int y = std::clamp(((g.block_y0[level] + j) << level) + half + g.origin.y, 0, g.height - 1);
      const size_t out = size_t(g.level_base[level]) + size_t(j) * size_t(w), in = size_t(y) * size_t(g.width);
      for (int i = 0; i < w; ++i) {
        const int x = std::clamp(((g.block_x0[level] + i) << level) + half + g.origin.x, 0, g.width - 1);
        ((records[out + size_t(i)] = records[in + size_t(x)]), ...);
      }
    }
  });
}

// A texel's occluder segment extent (Texel): from the second depth layer's back - front in
// planar depth where there is one (in perspective over the planar depth: the same ratio
// as along the view ray), else thickness_world (in perspective over |p|).
inline float segment_extent(const cv::Vec3f& p, float depth, const float* back_row, int x, float thickness_world,
                            bool perspective) {
  if (back_row != nullptr) {
    const float planar = back_row[x] > depth ? back_row[x] - depth : 0.0f;
    return perspective ? planar / depth : planar;
  }
  return perspective ? thickness_world / std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) : thickness_world;
}

// The texels and planes of level 0 and their coarser levels; each segment's thickness from
// `back` (the second depth layer) where given, else thickness_world.
void build_texels(const AoInputs& in, const cv::Mat* back, float thickness_world, const TapGrid& g,
                  UninitializedVector<Texel>& texels, UninitializedVector<TexelPlane>& planes, int nthreads) {
  const int width = in.depth_view.cols;
  const bool perspective = in.camera.is_perspective();
  // Before the parallel loops, which write every element (not zeroed first).
  texels.resize(size_t(g.texels));
  planes.resize(texels.size());
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const cv::Vec3f* pos_row = in.position_view.ptr<cv::Vec3f>(y);
      const cv::Vec3f* nor_row = in.normal_view.ptr<cv::Vec3f>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      const float* back_row = back != nullptr ? back->ptr<float>(y) : nullptr;
      Texel* out = texels.data() + size_t(y) * size_t(width);
      TexelPlane* out_plane = planes.data() + size_t(y) * size_t(width);
      for (int x = 0; x < width; ++x) {
        const cv::Vec3f& p = pos_row[x];
        const cv::Vec3f& n = nor_row[x];
        const float extent = segment_extent(p, depth_row[x], back_row, x, thickness_world, perspective);
        out[x] = mask_row[x] ? Texel{p[0], p[1], p[2], extent} : Texel{0.0f, 0.0f, 0.0f, -1.0f};
        out_plane[x] = mask_row[x] ? TexelPlane{n[0], n[1], n[2], n.dot(p)} : TexelPlane{0.0f, 0.0f, 0.0f, 0.0f};
      }
    }
  });
  build_coarse_levels(g, nthreads, texels.data(), planes.data());
}

// Normals within acos(0.95) = 18 deg of each other: the same plane up to the curvature
// between two taps (a cylinder of radius 1 turns by 18 deg over 0.3 units) or the rounding
// of reconstructed normals; creases of a box (90 deg) and floor-vs-underside (180 deg) are
// never connected this way.
constexpr float kCoplanarMinCos = 0.95f;

// Pixels shaded together, one per vector lane: four vector registers' worth per value (64
// on AVX-512, 32 on AVX2, 16 on NEON and the baseline; a tile row at most). Every loop over
// the lanes runs each pixel's operations in the same order as for the pixel alone, so the
// lanes change the speed, not the bits; the taps of a slice side then run in order of
// distance across the pixels, and the ordered pass of the visibility mask is a select per
// lane instead of a branch per tap. Four registers rather than one: a step's arithmetic is
// one long chain of dependent operations per register (square roots, divisions,
// arccosines), and independent registers in each loop keep the arithmetic units busy while
// a chain waits; more than four only add to the working set (docs/performance.md, "GTAO's
// groups of lanes"). Lanes without taps (background, sub-pixel radius, past the tile's
// edge) compute for nobody.
constexpr int kVectorLanes = int(hwy::HWY_NAMESPACE::MaxLanes(hwy::HWY_NAMESPACE::ScalableTag<float>()));
constexpr int kLanes = std::clamp(4 * kVectorLanes, 16, kTileWidthPx);
static_assert(kTileWidthPx % kLanes == 0);

// The lanes of the whole groups that hold a row of `pixels` pixels.
inline int group_lanes(int pixels) { return (pixels + kLanes - 1) / kLanes * kLanes; }

// A tap's texel index; below 0 there is no texel: off screen (nothing known there: the
// side's last tap ends), or no tap at all (the pixel has no taps, or the step's offset
// rounds to (0, 0): the side's last tap stays).
constexpr int32_t kOffScreen = -1;
constexpr int32_t kNoTap = -2;

// The settings turned into what the passes read, once per call (XeGTAO's GTAOConstants).
struct Constants {
  int slices;
  int steps;
  bool pool_slices;
  float radius_world;
  float max_radius_px;
  float thickness_world;
  bool height_field;  // thickness_world = inf: the paper's height-field occluders
  float depth_bias_relative;
  StratifiedNoise noise;  // of the seed: a pixel's slice rotation and step jitter
  bool multibounce;
  bool perspective;
  float r2;  // radius_world^2
  Falloff falloff;
  ScreenToView screen_to_view;
  TapGrid grid;
  LevelSelect levels;  // of grid
  const SectorTables* sectors;  // the visibility mask's sector measures
  // Slice angles i pi / slices as (cos, sin), rotated per pixel by one angle: no trig per
  // slice in the pixel loop.
  std::vector<std::array<float, 2>> slice_rot;

  Constants(const AoInputs& in, const AoSettings& s)
      : slices(s.directions),
        steps(s.steps),
        pool_slices(s.pool_slices),
        radius_world(s.radius_world),
        max_radius_px(s.max_radius_px),
        thickness_world(s.thickness_world),
        height_field(!std::isfinite(s.thickness_world)),
        depth_bias_relative(s.depth_bias_relative),
        noise(s.seed),
        multibounce(s.multibounce && in.albedo != nullptr && !in.albedo->empty()),
        perspective(in.camera.is_perspective()),
        r2(s.radius_world * s.radius_world),
        falloff(s.radius_world, s.falloff_fraction),
        screen_to_view(in.camera),
        grid{in.depth_view.cols, in.depth_view.rows, in.frame_origin_px, s.directions, s.steps},
        levels(grid),
        sectors(&sector_tables()),
        slice_rot(size_t(s.directions)) {
    for (int i = 0; i < slices; ++i) {
      // The float pi widened to double (the slice angles' bits depend on it).
      const double a = double(i) * double(std::numbers::pi_v<float>) / double(slices);
      slice_rot[size_t(i)] = {float(std::cos(a)), float(std::sin(a))};
    }
  }
};

// The frame as the taps read it: the G-buffer views and their texels.
struct Frame {
  const AoInputs& in;
  UninitializedVector<Texel> texels;
  UninitializedVector<TexelPlane> planes;
};

const cv::Mat* back_layer(const AoInputs& in, const Constants& k) {
  return !k.height_field && in.depth_back_view != nullptr && !in.depth_back_view->empty() &&
                 in.depth_back_view->size() == in.depth_view.size()
             ? in.depth_back_view
             : nullptr;
}

// A row of a tile, field by field so that loops over its pixels vectorise: the pixels' tap
// patterns (GTAO Alg. 1 lines 5-6 and the steps' jitter), and the shading's per-pixel
// sums, turned into the outputs for the whole row at once.
enum : uint8_t { kBackground, kNoTaps, kShaded };
struct TileRow {
  alignas(64) int32_t has_taps[kTileWidthPx];
  // Between its steps' taps: (projected radius - kMinTapDistancePx) / steps.
  alignas(64) float spacing_px[kTileWidthPx];
  alignas(64) int32_t level_cap[kTileWidthPx];  // the coarsest level its taps read
  alignas(64) float step_noise[kTileWidthPx];
  alignas(64) float rot_c[kTileWidthPx], rot_s[kTileWidthPx];  // the rotation of the slices
  alignas(64) uint8_t state[kTileWidthPx];
  alignas(64) float visible_sum[kTileWidthPx];
  alignas(64) float open_sum[kTileWidthPx];
  alignas(64) float bent_x[kTileWidthPx], bent_y[kTileWidthPx], bent_z[kTileWidthPx];
};

static_assert(kTileWidthPx <= 64, "a tile row's noise is one run of a HilbertTile row");

// The tap patterns of row y's pixels x0 .. x0 + n - 1 (at 0 .. n - 1 in the row), computed
// for every pixel and kept where it has taps (no branch: the loop vectorises).
inline void pixel_taps(const Constants& k, const AoInputs& in, int x0, int n, int y, TileRow& row) {
  const uint8_t* mask = in.mask.ptr<uint8_t>(y) + x0;
  const float* depth = in.depth_view.ptr<float>(y) + x0;
  // The frame's pixels (without a guard band's offset): their spatially stratified noise.
  const uint16_t* hilbert = StratifiedNoise::row_indices(x0 - in.frame_origin_px.x, y - in.frame_origin_px.y);
  for (int xi = 0; xi < n; ++xi) {
    const bool foreground = mask[xi] != 0;
    const float radius_px = projected_radius_px(in.camera, depth[xi], k.radius_world, k.max_radius_px);
    // Below 2 px the whole occlusion sphere fits in the pixel's neighbour: no tap can see it.
    const bool has_taps = foreground & !(radius_px < 2.0f * kMinTapDistancePx);
    const float slice_noise = k.noise.u(hilbert[xi]), step_noise = k.noise.v(hilbert[xi]);
    float rot_c, rot_s;
    // The rotation slice_noise pi / slices, in turns.
    sincos_turns(slice_noise / float(2 * k.slices), rot_c, rot_s);
    row.has_taps[xi] = has_taps;
    const float spacing_px = (radius_px - kMinTapDistancePx) / float(k.steps);
    row.spacing_px[xi] = has_taps ? spacing_px : 0.0f;
    row.level_cap[xi] = level_cap(row.spacing_px[xi]);
    row.step_noise[xi] = has_taps ? step_noise : 0.0f;
    row.rot_c[xi] = has_taps ? rot_c : 1.0f;
    row.rot_s[xi] = has_taps ? rot_s : 0.0f;
    row.state[xi] = !foreground ? kBackground : has_taps ? kShaded : kNoTaps;
  }
}

// Screen direction of slice i (px, y down): slice angle phi in [0, pi), rotated per pixel.
[[gnu::always_inline]] inline glm::vec2 slice_direction(const Constants& k, float rot_c, float rot_s, int i) {
  const std::array<float, 2>& r = k.slice_rot[size_t(i)];
  const float cos_phi = rot_c * r[0] - rot_s * r[1];
  const float sin_phi = rot_s * r[0] + rot_c * r[1];
  return glm::vec2(cos_phi, -sin_phi);
}

// Texel indices of the taps of step j of slice i, both sides, of the row's pixels xi0 ..
// xi0 + kLanes - 1 (x = x0 + xi), in lanes: pos[l] and neg[l] for pixel xi0 + l. dir_x,
// dir_y: the pixels' screen directions of the slice, by lane. `coarse`: some pixel's taps may
// read a coarse level (else every tap reads level 0, without the level's selects). In
// explicit vectors: the level's offset and width are a select per level, where GCC's
// vectorised scalar code spent five operations per level and array.
template <bool coarse>
inline void step_indices(const Constants& k, const TileRow& row, const float* dir_x, const float* dir_y, int x0,
                         int y, int xi0, int i, int j, int32_t* __restrict pos, int32_t* __restrict neg) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::CappedTag<float, kLanes> d;
  const hn::RebindToSigned<decltype(d)> di;
  const hn::RebindToUnsigned<decltype(d)> du;
  const TapGrid& g = k.grid;
  const LevelSelect& levels = k.levels;
  // R1 sequence per step (Roberts 2018) on top of the pixel's noise.
  const auto step_shift = hn::Set(d, float(i + j * g.slices) * 0.618033988749895f);
  const auto step = hn::Set(d, float(j)), min_dist = hn::Set(d, kMinTapDistancePx), half = hn::Set(d, 0.5f);
  const auto zero = hn::Zero(di), no_tap = hn::Set(di, kNoTap), off_screen = hn::Set(di, kOffScreen);
  const auto width = hn::Set(du, uint32_t(g.width)), height = hn::Set(du, uint32_t(g.height));
  const auto yv = hn::Set(di, y);
  // round_to_int in lanes.
  const auto round = [&](auto v) { return hn::ConvertTo(di, hn::Add(v, hn::CopySign(half, v))); };
  // 0 <= p < size as one unsigned compare per axis.
  const auto on_screen = [&](auto px, auto py) {
    return hn::RebindMask(di, hn::And(hn::Lt(hn::BitCast(du, px), width), hn::Lt(hn::BitCast(du, py), height)));
  };
  for (size_t l = 0; l < size_t(kLanes); l += hn::Lanes(d)) {
    const size_t xi = size_t(xi0) + l;
    auto t = hn::Add(hn::Load(d, row.step_noise + xi), step_shift);
    t = hn::Sub(t, hn::Floor(t));
    // Uniform in screen distance (distribution power 1). XeGTAO's power 2 puts taps near
    // the centre; against the ray-marched reference on the shared frames (cornell,
    // greeble, depthgap) power 1 halved the error at 8 steps (MAE 0.057 -> 0.040 on
    // cornell): far taps carry walls seen at grazing angles, whose occlusion the dense
    // near taps never see.
    const auto dist_px = hn::Add(min_dist, hn::Mul(hn::Add(step, t), hn::Load(d, row.spacing_px + xi)));
    // The positive side's offset; the negative side's is its negation.
    const auto ox = round(hn::Mul(hn::Load(d, dir_x + l), dist_px));
    const auto oy = round(hn::Mul(hn::Load(d, dir_y + l), dist_px));
    const auto tap = hn::And(hn::Ne(hn::Load(di, row.has_taps + xi), zero), hn::Ne(hn::Or(ox, oy), zero));
    const auto x = ssdo::HWY_NAMESPACE::iota_lanes(di, x0 + int(xi));
    const auto px = hn::Add(x, ox), py = hn::Add(yv, oy), nx = hn::Sub(x, ox), ny = hn::Sub(yv, oy);
    hn::Vec<decltype(di)> pos_index, neg_index;
    if constexpr (coarse) {
      // The largest L <= the pixel's cap with dist_px >= 2^(L + kFineTapsLog2) (dist_px >=
      // kMinTapDistancePx, a normal float).
      const auto log2_dist = ssdo::HWY_NAMESPACE::floor_log2_lanes(di, dist_px);
      const auto cap = hn::Load(di, row.level_cap + xi);
      const auto level = hn::Max(hn::Min(hn::Sub(log2_dist, hn::Set(di, kFineTapsLog2)), cap), zero);
      hn::Vec<decltype(di)> offset, w;
      if constexpr (hn::MaxLanes(di) > kCoarseLevels) {  // the level's entries by permutation
        const auto entry = hn::IndicesFromVec(di, level);
        offset = hn::TableLookupLanes(hn::Load(di, levels.offset), entry);
        w = hn::TableLookupLanes(hn::Load(di, levels.width), entry);
      } else {  // a select per level
        offset = hn::Set(di, levels.offset[0]), w = hn::Set(di, levels.width[0]);
        for (int lv = 1; lv <= kCoarseLevels; ++lv) {
          const auto reached = hn::Gt(level, hn::Set(di, lv - 1));
          offset = hn::IfThenElse(reached, hn::Set(di, levels.offset[lv]), offset);
          w = hn::IfThenElse(reached, hn::Set(di, levels.width[lv]), w);
        }
      }
      const auto index = [&](auto tx, auto ty) {
        const auto bx = hn::Sub(tx, hn::Set(di, levels.origin.x)) >> level;
        const auto by = hn::Sub(ty, hn::Set(di, levels.origin.y)) >> level;
        return hn::Add(hn::Add(offset, hn::Mul(by, w)), bx);
      };
      pos_index = index(px, py), neg_index = index(nx, ny);
    } else {
      const auto centre = ssdo::HWY_NAMESPACE::iota_lanes(di, y * g.width + x0 + int(xi));
      const auto offset = hn::Add(hn::Mul(oy, hn::Set(di, g.width)), ox);
      pos_index = hn::Add(centre, offset), neg_index = hn::Sub(centre, offset);
    }
    hn::Store(hn::IfThenElse(tap, hn::IfThenElse(on_screen(px, py), pos_index, off_screen), no_tap), di, pos + l);
    hn::Store(hn::IfThenElse(tap, hn::IfThenElse(on_screen(nx, ny), neg_index, off_screen), no_tap), di, neg + l);
  }
}

// step_indices of the group of lanes at xi0, with the level selects only where some pixel
// of the group has a coarse level to read.
inline void group_step_indices(const Constants& k, const TileRow& row, const float* dir_x, const float* dir_y, int x0,
                               int y, int xi0, int i, int j, int32_t* __restrict pos, int32_t* __restrict neg) {
  int32_t cap = 0;
  for (int l = 0; l < kLanes; ++l) cap |= row.level_cap[xi0 + l];
  if (cap != 0)
    step_indices<true>(k, row, dir_x, dir_y, x0, y, xi0, i, j, pos, neg);
  else
    step_indices<false>(k, row, dir_x, dir_y, x0, y, xi0, i, j, pos, neg);
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

// What a slice adds to its pixel's point (GTAO Alg. 1 lines 8-16): its direction and axis,
// the origin in its frame, its angle n and measures.
struct SliceFields {
  glm::vec3 dir, axis;
  float origin_v, origin_d, origin_a;
  float cos_n, sin_n;
  float pn_len, weight_total;
};

[[gnu::always_inline]] inline SliceFields slice_fields(const Constants& k, const PixelPoint& px, glm::vec2 d) {
  const Slice sl = make_slice(k.screen_to_view(d.x, d.y), px.view, px.normal);
  // n = sign acos(cos_n), so sin n = sign sqrt(1 - cos_n^2) and the tangent limits
  // n +- pi/2 have cos = -+sin n: no trig per slice.
  const float cos_n = sl.cos_n;
  const float sin_n = std::copysign(std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n)), sl.n);
  // Slice measure in total (inner integral from n - pi/2 to n + pi/2).
  const float weight_total = cos_n + sl.n * sin_n;
  // The origin in the slice's orthonormal frame (per slice, so that each tap needs three dot
  // products).
  const glm::vec3 &origin = px.origin, &dir = sl.direction, &axis = sl.axis;
  return {dir,   axis,  glm::dot(origin, px.view), glm::dot(origin, dir), glm::dot(origin, axis),
          cos_n, sin_n, sl.projected_normal_length, weight_total};
}

// The visibility mask's sector holding the view vector (sector_u of f = -n), and that
// sector's measure: from its lower edge up to the view vector and from there to its upper
// edge, each side's antiderivative (SectorTables) taken from its value at f = -n,
// cos n G1(-n) + sin n G2(-n) = -n sin n / 2 (n sin n = weight_total - cos n). A normal
// facing away (cos n <= 0) puts the view vector past a limit: every sector then lies on
// one side of it. Apart from the slice's other fields, whose loop has no table reads.
inline void split_sector(const SectorTables& t, float cos_n, float sin_n, float weight_total, int32_t& split,
                         float& split_measure) {
  const float u_view = sector_u(1.0f, 0.0f, cos_n, sin_n, sin_n > 0.0f ? 0.0f : 1.0f);
  const int32_t k = std::clamp(int32_t(u_view * kSectors), 0, kSectors - 1);
  const float edge_lo = cos_n * t.g1[k] + sin_n * t.g2[k];
  const float edge_hi = cos_n * t.g1[k + 1] + sin_n * t.g2[k + 1];
  const float straddled = edge_lo + edge_hi + (weight_total - cos_n);
  split = k;
  split_measure = cos_n > 0.0f ? straddled : k == 0 ? edge_hi - edge_lo : edge_lo - edge_hi;
}

// The points of a tile row's pixels, field by field (pixel xi at [c][xi]).
struct RowPoints {
  alignas(64) float origin[3][kTileWidthPx], normal[3][kTileWidthPx], view[3][kTileWidthPx];

  void set(size_t xi, const PixelPoint& p) {
    for (int c = 0; c < 3; ++c) origin[c][xi] = p.origin[c], normal[c][xi] = p.normal[c], view[c][xi] = p.view[c];
  }
  PixelPoint at(size_t xi) const {
    return {{origin[0][xi], origin[1][xi], origin[2][xi]},
            {normal[0][xi], normal[1][xi], normal[2][xi]},
            {view[0][xi], view[1][xi], view[2][xi]}};
  }
};

// Slice i of the pixels of a group (lanes), as the taps' arithmetic reads it: the pixel's
// point, the slice's frame and measures, its screen direction.
struct SliceLanes {
  alignas(64) float ox[kLanes], oy[kLanes], oz[kLanes];  // biased origin
  alignas(64) float nx[kLanes], ny[kLanes], nz[kLanes];  // normal
  alignas(64) float vx[kLanes], vy[kLanes], vz[kLanes];  // view vector
  alignas(64) float dx[kLanes], dy[kLanes], dz[kLanes];  // slice direction
  alignas(64) float ax[kLanes], ay[kLanes], az[kLanes];  // slice axis
  alignas(64) float origin_v[kLanes], origin_d[kLanes], origin_a[kLanes];  // the origin in the slice frame
  alignas(64) float cos_n[kLanes], sin_n[kLanes];  // the projected normal's angle n
  alignas(64) float pn_len[kLanes], weight_total[kLanes];   // |projected normal|, the slice measure
  alignas(64) int32_t split[kLanes];                        // the view vector's sector
  alignas(64) float split_measure[kLanes];                  // and its measure
  alignas(64) float screen_x[kLanes], screen_y[kLanes];     // slice_direction

  // Slice i of the row's pixels xi0 .. xi0 + kLanes - 1, a chain of divisions and square
  // roots per lane (no branch: the loops vectorise).
  [[gnu::always_inline]] void compute(const Constants& k, const TileRow& row, const RowPoints& points, int i,
                                      int xi0) {
    for (int l = 0; l < kLanes; ++l) {
      const size_t x = size_t(xi0 + l);
      const PixelPoint p = points.at(x);
      const glm::vec2 d = slice_direction(k, row.rot_c[x], row.rot_s[x], i);
      const SliceFields f = slice_fields(k, p, d);
      ox[l] = p.origin.x, oy[l] = p.origin.y, oz[l] = p.origin.z;
      nx[l] = p.normal.x, ny[l] = p.normal.y, nz[l] = p.normal.z;
      vx[l] = p.view.x, vy[l] = p.view.y, vz[l] = p.view.z;
      dx[l] = f.dir.x, dy[l] = f.dir.y, dz[l] = f.dir.z;
      ax[l] = f.axis.x, ay[l] = f.axis.y, az[l] = f.axis.z;
      origin_v[l] = f.origin_v, origin_d[l] = f.origin_d, origin_a[l] = f.origin_a;
      cos_n[l] = f.cos_n, sin_n[l] = f.sin_n;
      pn_len[l] = f.pn_len, weight_total[l] = f.weight_total;
      screen_x[l] = d.x, screen_y[l] = d.y;
    }
    for (int l = 0; l < kLanes; ++l)
      split_sector(*k.sectors, cos_n[l], sin_n[l], weight_total[l], split[l], split_measure[l]);
  }
};

// The taps of one step of one side of a slice, across the group's pixels (lanes): texel
// index, the texel, its coordinates in the slice frame, its height above the tangent plane
// (only its sign is used), its squared distance in the slice plane and in 3D, the cosine c
// of its angle in the slice as c |c| (its order without a square root: signed_sqrt gives c
// back), and the occluded interval [u0, u1] of its segment in the mask (u0 > u1: none).
struct StepLanes {
  alignas(64) int32_t index[kLanes];
  alignas(64) float x[kLanes], y[kLanes], z[kLanes], extent[kLanes];
  alignas(64) float dv[kLanes], dd[kLanes], da[kLanes];
  alignas(64) float height[kLanes], dist_slice2[kLanes], dist2[kLanes], tap_cos_sq[kLanes];
  alignas(64) float u0[kLanes], u1[kLanes];
  // An occluder the ordered pass reads: on screen, foreground, above the tangent plane,
  // off the slice's centre (set by step_coordinates).
  alignas(64) int32_t occluder[kLanes];
};

[[gnu::always_inline]] inline bool occluder(const StepLanes& t, int l) { return t.occluder[l] != 0; }

// The 16-byte records (Texel, TexelPlane) at index[l] of `records` for a vector's lanes (from
// index[0]), one load each, transposed to their four fields (load_records4): field[f] lane l
// = field f of record index[l]. Lanes with index < 0 read record 0's, for nobody.
template <class D, class Record>
HWY_INLINE void record_lanes(D d, const Record* records, const int32_t* index, hwy::HWY_NAMESPACE::Vec<D>* field) {
  namespace hn = hwy::HWY_NAMESPACE;
  static_assert(sizeof(Record) == 4 * sizeof(float));
  const hn::RebindToSigned<D> di;
  HWY_ALIGN int32_t offset[hn::MaxLanes(d)];
  hn::Store(hn::ShiftLeft<2>(hn::Max(hn::Load(di, index), hn::Zero(di))), di, offset);
  ssdo::HWY_NAMESPACE::load_records4(d, reinterpret_cast<const float*>(records), offset, field);
}

// The taps' texels in lanes.
inline void gather_texels(const Texel* texels, StepLanes& t) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::CappedTag<float, kLanes> d;
  for (size_t l = 0; l < size_t(kLanes); l += hn::Lanes(d)) {
    hn::Vec<decltype(d)> v[4];
    record_lanes(d, texels, t.index + l, v);
    hn::Store(v[0], d, t.x + l), hn::Store(v[1], d, t.y + l), hn::Store(v[2], d, t.z + l);
    hn::Store(v[3], d, t.extent + l);
  }
}

// The taps' texels and coordinates in the slice frame (no branches: the loop vectorises).
// Returns whether some lane is an occluder.
[[gnu::noinline]] bool step_coordinates(const Texel* texels, const SliceLanes& s, StepLanes& __restrict t) {
  gather_texels(texels, t);
  int occluders = 0;
  for (int l = 0; l < kLanes; ++l) {
    const int32_t index = t.index[l];
    const Texel tx{t.x[l], t.y[l], t.z[l], t.extent[l]};
    const float ex = tx.x - s.ox[l], ey = tx.y - s.oy[l], ez = tx.z - s.oz[l];
    const float height = ex * s.nx[l] + ey * s.ny[l] + ez * s.nz[l];
    // The tap in the slice's orthonormal frame (view, direction, axis): the slice plane
    // holds the first two coordinates, so the projection onto the plane is dropping the
    // third (no 3D projection per tap).
    const float dv = ex * s.vx[l] + ey * s.vy[l] + ez * s.vz[l];
    const float dd = ex * s.dx[l] + ey * s.dy[l] + ez * s.dz[l];
    const float da = ex * s.ax[l] + ey * s.ay[l] + ez * s.az[l];
    const float dist_slice2 = dv * dv + dd * dd;
    t.dv[l] = dv;
    t.dd[l] = dd;
    t.da[l] = da;
    t.height[l] = height;
    t.dist_slice2[l] = dist_slice2;
    t.dist2[l] = dist_slice2 + da * da;
    // The tap's angle in the slice: of its projection onto the slice plane.
    t.tap_cos_sq[l] = dv * std::abs(dv) / dist_slice2;
    t.occluder[l] = (index >= 0) & (tx.extent >= 0.0f) & (height > 0.0f) & (dist_slice2 > 0.0f);
    occluders |= t.occluder[l];
  }
  return occluders != 0;
}

// The occluded interval [u0, u1] of each lane's occluder segment on side `side` (0: +, 1:
// -), as positions in the visibility mask (sector_u); (1, 0) where the segment misses. The
// ordered pass reads the intervals of a step with some occluder, and of its occluders only
// (visibility_mask_step): a vector of lanes without an occluder gets (1, 0) without the
// arithmetic.
template <bool perspective>
[[gnu::noinline]] void step_intervals(const Constants& k, const SliceLanes& s, int side, StepLanes& __restrict t) {
  const float r2 = k.r2;
  // The side's sign of the direction coordinate, and its limit in the mask.
  const float sign = side == 0 ? 1.0f : -1.0f, side_u = side == 0 ? 1.0f : 0.0f;
  // A vector of lanes, but at least 8: GCC unrolls a loop of 4 lanes (SSE2, NEON)
  // completely and leaves the lanes scalar.
  constexpr int kChunk = std::max(kVectorLanes, 8);
  static_assert(kLanes % kChunk == 0);
  for (int l0 = 0; l0 < kLanes; l0 += kChunk) {
    int occluders = 0;
    for (int l = l0; l < l0 + kChunk; ++l) occluders |= t.occluder[l];
    if (!occluders) {
      for (int l = l0; l < l0 + kChunk; ++l) t.u0[l] = 1.0f, t.u1[l] = 0.0f;
      continue;
    }
    for (int l = l0; l < l0 + kChunk; ++l) {
      const float dv = t.dv[l], dd = t.dd[l], da = t.da[l], dist2 = t.dist2[l];
      const float cos_n = s.cos_n[l], sin_n = s.sin_n[l];
      // The occluder segment (Texel) delta + t r, t in [0, extent], clipped to the radius
      // sphere |delta + t r| <= radius: a t^2 + 2 b t + c <= 0 with a = |r|^2, b = delta . r,
      // c = |delta|^2 - radius^2; r in the slice frame: orthographic, the unit view axis
      // (a = 1); perspective, the tap's position p itself (the origin's frame coordinates
      // plus delta's), a = |p|^2. Lanes without a texel read texel 0's extent, for nobody.
      float rv = -s.vz[l], rd = -s.dz[l], ra = -s.az[l];
      if constexpr (perspective) rv = s.origin_v[l] + dv, rd = s.origin_d[l] + dd, ra = s.origin_a[l] + da;
      const float b = dv * rv + dd * rd + da * ra;
      const float c = dist2 - r2;
      float disc = b * b - c, inv_a = 1.0f;
      if constexpr (perspective) {
        const float a = rv * rv + rd * rd + ra * ra;
        disc = b * b - a * c;
        inv_a = 1.0f / a;
      }
      // disc < 0 (the ray misses the sphere): root is NaN, the lane is not hit below.
      const float root = std::sqrt(disc);
      const float t0 = std::max(0.0f, (-b - root) * inv_a);
      const float t1 = std::min(t.extent[l], (-b + root) * inv_a);
      // The segment's two ends in the slice plane, on the tap's side of the view vector
      // (|direction coordinate| with the side's sign), as positions in the mask.
      const float e0v = dv + t0 * rv, e0d = sign * std::abs(dd + t0 * rd);
      const float e1v = dv + t1 * rv, e1d = sign * std::abs(dd + t1 * rd);
      const float w0 = sector_u(e0v, e0d, cos_n, sin_n, side_u);
      const float w1 = sector_u(e1v, e1d, cos_n, sin_n, side_u);
      const float u0 = std::min(w0, w1), u1 = std::max(w0, w1);
      // Some of the segment above the tangent line (cos f > 0 at an end).
      const bool above = (e0v * cos_n + e0d * sin_n > 0.0f) | (e1v * cos_n + e1d * sin_n > 0.0f);
      const bool hit = (disc >= 0.0f) & (t1 >= t0) & above;
      t.u0[l] = hit ? u0 : 1.0f;  // empty: u0 > u1
      t.u1[l] = hit ? u1 : 0.0f;
    }
  }
}

// Height-field horizons (GTAO Alg. 1 lines 17-26, the paper's occluder model): per side,
// the tap direction closest to the view vector, lerped towards the lowest horizon (the
// tangent limit, -+sin n) by the distance falloff (GTAO sec. 4.3, "Bounding the sampling
// area"; XeGTAO). Only occluders raise the horizon.
inline void height_field_step(const Constants& k, const SliceLanes& s, const StepLanes& t, int side,
                              float* __restrict horizon_cos) {
  for (int l = 0; l < kLanes; ++l) {
    const float low_cos = side == 0 ? -s.sin_n[l] : s.sin_n[l];
    const float w = k.falloff(std::sqrt(t.dist2[l]));
    const float raised = std::max(horizon_cos[l], low_cos + (signed_sqrt(t.tap_cos_sq[l]) - low_cos) * w);
    horizon_cos[l] = occluder(t, l) ? raised : horizon_cos[l];
  }
}

// A side's last tap per lane, for the connection rule (top of this file): its depth (< 0:
// none to connect to), its occluded interval in the mask, its texel,
// whether it was on or below the tangent plane (its interval is then the tangent limit);
// and the side's horizon: its cosine c from the view vector (height field), or c |c|
// (visibility mask, whose taps compare their tap_cos_sq).
struct SideLanes {
  alignas(64) float depth_view[kLanes], u0[kLanes], u1[kLanes];
  alignas(64) int32_t texel[kLanes];
  alignas(64) int32_t below[kLanes];
  alignas(64) float horizon[kLanes];
};

// Which of a vector's lanes (from lane l) that have an interval (`has`) continue their
// side's last tap (the connection rule): the depths within the thickness; from the tangent
// plane, the two points within the thickness in 3D (a wall standing on the floor, never the
// gap under a floating object); or the two taps on one plane. Each of the last two tests
// gathers its records only when some lane of the vector needs it.
template <class D>
HWY_INLINE hwy::HWY_NAMESPACE::Mask<D> connected_lanes(D d, const Constants& k, const Frame& f,
                                                       const StepLanes& __restrict t, const SideLanes& __restrict st,
                                                       size_t l, hwy::HWY_NAMESPACE::Mask<D> has) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::RebindToSigned<D> di;
  const float thickness = k.thickness_world;
  const auto st_depth = hn::Load(d, st.depth_view + l);
  const auto has_last = hn::And(has, hn::Ge(st_depth, hn::Zero(d)));
  const auto below = hn::RebindMask(d, hn::Ne(hn::Load(di, st.below + l), hn::Zero(di)));
  const auto by_depth = hn::Le(hn::Abs(hn::Sub(hn::Neg(hn::Load(d, t.z + l)), st_depth)), hn::Set(d, thickness));
  const auto above_last = hn::AndNot(below, has_last);
  const auto near_lanes = hn::And(has_last, below);
  const auto plane_lanes = hn::AndNot(by_depth, above_last);
  auto connect = hn::And(above_last, by_depth);
  if (!hn::AllFalse(d, near_lanes)) {
    hn::Vec<D> last[4];
    record_lanes(d, f.texels.data(), st.texel + l, last);
    const auto ddx = hn::Sub(hn::Load(d, t.x + l), last[0]), ddy = hn::Sub(hn::Load(d, t.y + l), last[1]);
    const auto ddz = hn::Sub(hn::Load(d, t.z + l), last[2]);
    const auto dist2 = hn::Add(hn::Add(hn::Mul(ddx, ddx), hn::Mul(ddy, ddy)), hn::Mul(ddz, ddz));
    connect = hn::Or(connect, hn::And(near_lanes, hn::Le(dist2, hn::Set(d, thickness * thickness))));
  }
  if (!hn::AllFalse(d, plane_lanes)) {
    // The tap on the last tap's tangent plane within the thickness, and their normals
    // agreeing: the same surface.
    hn::Vec<D> a[4], b[4];
    record_lanes(d, f.planes.data(), st.texel + l, a);
    record_lanes(d, f.planes.data(), t.index + l, b);
    const auto cos = hn::Add(hn::Add(hn::Mul(a[0], b[0]), hn::Mul(a[1], b[1])), hn::Mul(a[2], b[2]));
    const auto on_plane =
        hn::Sub(hn::Add(hn::Add(hn::Mul(a[0], hn::Load(d, t.x + l)), hn::Mul(a[1], hn::Load(d, t.y + l))),
                        hn::Mul(a[2], hn::Load(d, t.z + l))),
                a[3]);
    const auto coplanar =
        hn::And(hn::Ge(cos, hn::Set(d, kCoplanarMinCos)), hn::Le(hn::Abs(on_plane), hn::Set(d, thickness)));
    connect = hn::Or(connect, hn::And(plane_lanes, coplanar));
  }
  return connect;
}

// The ordered pass's update of a side from its step, for a vector's lanes from lane l:
// the occluded range [h0, h1] the step adds to the mask (the tap's interval where `has`,
// joined with the side's last one where `joined`; (1, 0) without one), the side's horizon
// (the taps within the radius), and its last tap. std::min and std::max as selects (their
// operand order on ties and zeros). The taps' intervals (t.u0, t.u1) are read only where
// some lane has one (`some`).
template <class D>
HWY_INLINE void update_side_lanes(D d, const Constants& k, const StepLanes& __restrict t, int side, size_t l,
                                  hwy::HWY_NAMESPACE::Mask<D> has, bool some, hwy::HWY_NAMESPACE::Mask<D> joined,
                                  SideLanes& __restrict st, hwy::HWY_NAMESPACE::Vec<D>& h0,
                                  hwy::HWY_NAMESPACE::Vec<D>& h1) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::RebindToSigned<D> di;
  const auto zero = hn::Zero(d);
  const auto zero_i = hn::Zero(di);
  // A tap on or below the tangent plane connects at the tangent limit: u = 1 on the
  // positive side, 0 on the other.
  const auto u_lim = hn::Set(d, side == 0 ? 1.0f : 0.0f);
  const auto index = hn::Load(di, t.index + l);
  const auto depth = hn::Neg(hn::Load(d, t.z + l));  // planar
  const auto foreground =
      hn::And(hn::RebindMask(d, hn::Gt(index, hn::Set(di, -1))), hn::Ge(hn::Load(d, t.extent + l), zero));
  // A tap on or below the tangent plane cannot occlude the hemisphere (nor can the rest
  // of its segment, which runs away from the eye, i.e. further down). Testing in 3D
  // first matters: rounding taps to pixel centres moves them off the slice, and their
  // slice angle alone would put tilted planes above their own tangent line.
  const auto up = hn::Gt(hn::Load(d, t.height + l), zero);
  const auto above = hn::And(foreground, up);
  const auto below = hn::AndNot(up, foreground);
  const auto centre = hn::AndNot(hn::Gt(hn::Load(d, t.dist_slice2 + l), zero), above);  // on the centre line
  const auto in_radius = hn::And(hn::RebindMask(d, hn::Ne(hn::Load(di, t.occluder + l), zero_i)),
                                 hn::Le(hn::Load(d, t.dist2 + l), hn::Set(d, k.r2)));
  const auto horizon = hn::Load(d, st.horizon + l), tap = hn::Load(d, t.tap_cos_sq + l);
  hn::Store(hn::IfThenElse(hn::And(in_radius, hn::Lt(horizon, tap)), tap, horizon), d, st.horizon + l);
  const auto su0 = hn::Load(d, st.u0 + l), su1 = hn::Load(d, st.u1 + l);
  const auto tu0 = some ? hn::Load(d, t.u0 + l) : u_lim, tu1 = some ? hn::Load(d, t.u1 + l) : u_lim;
  // The occluded range, as an empty one (1, 0) without an interval.
  const auto lo = hn::IfThenElse(hn::And(joined, hn::Lt(su0, tu0)), su0, tu0);  // std::min(tu0, su0)
  const auto hi = hn::IfThenElse(hn::And(joined, hn::Lt(tu1, su1)), su1, tu1);  // std::max(tu1, su1)
  h0 = hn::IfThenElse(has, lo, hn::Set(d, 1.0f));
  h1 = hn::IfThenElseZero(has, hi);
  // The side's last tap: unchanged without a tap or on the centre line; else this one,
  // with nothing to connect to off screen, on background and beyond the radius.
  const auto keep = hn::Or(hn::RebindMask(d, hn::Eq(index, hn::Set(di, kNoTap))), centre);
  const auto last_depth = hn::IfThenElse(hn::Or(has, below), depth, hn::Set(d, -1.0f));
  hn::Store(hn::IfThenElse(keep, hn::Load(d, st.depth_view + l), last_depth), d, st.depth_view + l);
  hn::Store(hn::IfThenElse(keep, su0, hn::IfThenElse(has, tu0, u_lim)), d, st.u0 + l);
  hn::Store(hn::IfThenElse(keep, su1, hn::IfThenElse(has, tu1, u_lim)), d, st.u1 + l);
  const auto keep_i = hn::RebindMask(di, keep);
  hn::Store(hn::IfThenElse(keep_i, hn::Load(di, st.texel + l), hn::Max(index, zero_i)), di, st.texel + l);
  const auto below_i = hn::IfThenElseZero(hn::RebindMask(di, below), hn::Set(di, 1));
  hn::Store(hn::IfThenElse(keep_i, hn::Load(di, st.below + l), below_i), di, st.below + l);
}

// The sectors whose centres lie in [u0, u1] of each lane (u = (p + 1) / 2 of the pseudo-angle
// p) set in its mask, occupied[l] for the vector's lanes: the first sector and how many
// (none where u1 < u0), then their 64-bit runs.
template <class D>
HWY_INLINE void add_sector_range(D d, hwy::HWY_NAMESPACE::Vec<D> u0, hwy::HWY_NAMESPACE::Vec<D> u1,
                                 uint64_t* occupied) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::RebindToSigned<D> di;
  const auto sectors = hn::Set(d, float(kSectors)), half = hn::Set(d, 0.5f);
  const auto last_sector = hn::Set(di, kSectors - 1);
  const auto first = hn::Max(hn::Zero(di), hn::ConvertTo(di, hn::Ceil(hn::Sub(hn::Mul(u0, sectors), half))));
  const auto last = hn::Min(last_sector, hn::ConvertTo(di, hn::Floor(hn::Sub(hn::Mul(u1, sectors), half))));
  HWY_ALIGN int32_t k0[hn::MaxLanes(d)], count[hn::MaxLanes(d)];
  hn::Store(hn::Max(hn::Add(hn::Sub(last, first), hn::Set(di, 1)), hn::Zero(di)), di, count);
  hn::Store(hn::Min(first, last_sector), di, k0);  // only an empty range starts past the last sector
  add_sector_runs(k0, count, occupied, hn::Lanes(d));
}

// One step of side `side` of the visibility mask (Therrien et al. 2023; finite
// thickness_world) of each lane, a vector of lanes at a time: the sectors the tap's segment
// occludes, with the side's last tap's when they connect, into `occupied`; the side's last
// tap and its horizon (the taps within the radius) updated. `occluders`: some lane's tap is
// one (step_coordinates); without one (half of a frame's steps, on open surfaces) the
// intervals are not read, and a vector without an interval neither tests connections nor
// adds sectors: only its side's last taps change.
[[gnu::noinline]] void visibility_mask_step(const Constants& k, const Frame& f, const StepLanes& __restrict t, int side,
                                            bool occluders, SideLanes& __restrict st, uint64_t* __restrict occupied) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::CappedTag<float, kLanes> d;
  const hn::RebindToSigned<decltype(d)> di;
  const auto none = hn::FirstN(d, 0);
  for (size_t l = 0; l < size_t(kLanes); l += hn::Lanes(d)) {
    auto has = none, joined = none;
    bool some = false;  // some lane has an interval
    if (occluders) {
      const auto occluder = hn::RebindMask(d, hn::Ne(hn::Load(di, t.occluder + l), hn::Zero(di)));
      has = hn::AndNot(hn::Gt(hn::Load(d, t.u0 + l), hn::Load(d, t.u1 + l)), occluder);
      some = !hn::AllFalse(d, has);
      if (some) joined = connected_lanes(d, k, f, t, st, l, has);
    }
    hn::Vec<decltype(d)> h0, h1;
    update_side_lanes(d, k, t, side, l, has, some, joined, st, h0, h1);
    if (some) add_sector_range(d, h0, h1, occupied + l);
  }
}

// The height-field slice integral: the visible measure between the two horizons (GTAO
// eq. 10's inner integral per side, Alg. 1 lines 27-29); positive side +acos, negative -acos.
// Both horizons at the tangent limits (-+sin n, none raised): the slice's whole measure,
// exactly (the arccosine's 7e-5 rad would leave an open slice short of it).
inline float height_field_integral(float cos_pos, float cos_neg, float cos_n, float sin_n, float weight_total) {
  const float h_pos = fast_acos(cos_pos);
  const float h_neg = -fast_acos(cos_neg);
  const float sp = std::sqrt(std::max(0.0f, 1.0f - cos_pos * cos_pos));
  const float sm = -std::sqrt(std::max(0.0f, 1.0f - cos_neg * cos_neg));
  const float visible =
      inner_integral(h_pos, cos_pos, sp, cos_n, sin_n) + inner_integral(h_neg, cos_neg, sm, cos_n, sin_n);
  return ((cos_pos == -sin_n) & (cos_neg == sin_n)) ? weight_total : visible;
}
// The visibility-mask slice integrals of a group's lanes: each slice's measure less its
// occupied sectors', so that a slice without occluders is exactly its measure. The sectors
// above the view vector's (`split`) weigh +(cos n dG1 + sin n dG2), those below it the
// negative (SectorTables), the split sector split_measure. A vector of 64-bit lanes (the
// masks) at a time, a gather per byte of each mask; std::clamp's selects.
inline void visibility_mask_integrals(const SectorTables& t, const uint64_t* occupied, const SliceLanes& s,
                                      float* visible) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::CappedTag<uint64_t, kLanes> du;
  const hn::RebindToSigned<decltype(du)> di;
  const hn::Rebind<uint32_t, decltype(du)> du32;
  const hn::Rebind<int32_t, decltype(du)> d32;
  const hn::Rebind<float, decltype(du)> df;
  const auto one = hn::Set(du, 1), byte = hn::Set(du, 255);
  const auto zero = hn::Zero(df);
  for (size_t l = 0; l < size_t(kLanes); l += hn::Lanes(du)) {
    const auto occ = hn::Load(du, occupied + l);
    const auto split_bit = hn::Shl(one, hn::BitCast(du, hn::PromoteTo(di, hn::Load(d32, s.split + l))));
    const auto below = hn::Sub(split_bit, one);
    const auto lo = hn::And(occ, below), hi = hn::AndNot(hn::Or(below, split_bit), occ);
    // The bytes set in some lane: a byte clear in every lane would add +0 - +0 to both sums
    // (byte_g's entry for 0), which leaves them as they are.
    HWY_ALIGN uint64_t lane_bits[hn::MaxLanes(du)];
    hn::Store(hn::Or(lo, hi), du, lane_bits);
    uint64_t bits = 0;
    for (size_t i = 0; i < hn::Lanes(du); ++i) bits |= lane_bits[i];
    auto g1 = zero, g2 = zero;
    for (int b = 0; b < 8; ++b) {
      if ((bits >> (8 * b) & 255) == 0) continue;
      const auto offset = hn::Set(du, uint64_t(256 * b));
      const auto hi_byte = hn::Add(hn::And(hn::ShiftRightSame(hi, 8 * b), byte), offset);
      const auto lo_byte = hn::Add(hn::And(hn::ShiftRightSame(lo, 8 * b), byte), offset);
      const auto g_hi = hn::GatherIndex(du, t.byte_g, hn::BitCast(di, hi_byte));
      const auto g_lo = hn::GatherIndex(du, t.byte_g, hn::BitCast(di, lo_byte));
      const auto first = [&](auto v) { return hn::BitCast(df, hn::TruncateTo(du32, v)); };
      const auto second = [&](auto v) { return hn::BitCast(df, hn::TruncateTo(du32, hn::ShiftRight<32>(v))); };
      g1 = hn::Add(g1, hn::Sub(first(g_hi), first(g_lo)));
      g2 = hn::Add(g2, hn::Sub(second(g_hi), second(g_lo)));
    }
    const auto split_on = hn::BitCast(df, hn::TruncateTo(du32, hn::VecFromMask(du, hn::TestBit(occ, split_bit))));
    const auto split_part = hn::And(split_on, hn::Load(df, s.split_measure + l));
    const auto occluded =
        hn::Add(hn::Add(hn::Mul(hn::Load(df, s.cos_n + l), g1), hn::Mul(hn::Load(df, s.sin_n + l), g2)), split_part);
    const auto total = hn::Load(df, s.weight_total + l);
    const auto v = hn::Sub(total, occluded);
    const auto low = hn::IfThenElse(hn::Lt(v, zero), zero, v);
    hn::Store(hn::IfThenElse(hn::Lt(total, low), total, low), df, visible + l);
  }
}

// The slice's bent normal, weighted by |pn|, added to (x, y, z): its cosine-weighted mean
// visible direction between the horizons (closed forms, see bent_a and bent_b). h_pos =
// acos(cp) in [0, pi] has sin >= 0, h_neg = -acos(cm) has sin <= 0.
[[gnu::always_inline]] inline void add_slice_bent_normal(float cp, float cm, const SliceLanes& s, int l, float& x,
                                                         float& y, float& z) {
  const float cos_n = s.cos_n[l], sin_n = s.sin_n[l];
  const float sp = std::sqrt(std::max(0.0f, 1.0f - cp * cp));
  const float sm = -std::sqrt(std::max(0.0f, 1.0f - cm * cm));
  const float a0 = bent_a(1.0f, 0.0f, cos_n, sin_n), b0 = bent_b(1.0f, 0.0f, cos_n, sin_n);
  const float along_view = bent_a(cp, sp, cos_n, sin_n) + bent_a(cm, sm, cos_n, sin_n) - 2.0f * a0;
  const float along_dir = bent_b(cp, sp, cos_n, sin_n) + bent_b(cm, sm, cos_n, sin_n) - 2.0f * b0;
  const float pn_len = s.pn_len[l];
  x += pn_len * (along_view * s.vx[l] + along_dir * s.dx[l]);
  y += pn_len * (along_view * s.vy[l] + along_dir * s.dy[l]);
  z += pn_len * (along_view * s.vz[l] + along_dir * s.dz[l]);
}

// A group's sums over its slices, per lane: the visible and the unoccluded measure, the
// bent normal.
struct GroupSums {
  alignas(64) float visible[kLanes] = {}, open[kLanes] = {};
  alignas(64) float bent_x[kLanes] = {}, bent_y[kLanes] = {}, bent_z[kLanes] = {};
};

// Slice i of the group of pixels xi0 .. xi0 + kLanes - 1 of row y (GTAO Alg. 1 lines 5-30):
// its taps step by step in order of distance, both sides, under the occluder model; its
// visible measure and bent normal added to the sums.
void shade_slice(const Constants& k, const Frame& f, const TileRow& row, const SliceLanes& s, int x0, int y,
                 int xi0, int i, GroupSums& sums) {
  SideLanes side[2];
  for (int l = 0; l < kLanes; ++l)
    for (int sd = 0; sd < 2; ++sd) {
      side[sd].depth_view[l] = -1.0f;
      side[sd].u0[l] = 1.0f, side[sd].u1[l] = 0.0f;
      side[sd].texel[l] = 0, side[sd].below[l] = 0;
      // The tangent limits, -+sin n: the lowest horizons.
      const float low = sd == 0 ? -s.sin_n[l] : s.sin_n[l];
      side[sd].horizon[l] = k.height_field ? low : low * std::abs(low);
    }
  alignas(64) uint64_t occupied[kLanes] = {};
  for (int j = 0; j < k.steps; ++j) {
    StepLanes t[2];
    group_step_indices(k, row, s.screen_x, s.screen_y, x0, y, xi0, i, j, t[0].index, t[1].index);
    for (int sd = 0; sd < 2; ++sd) {
      const bool occluders = step_coordinates(f.texels.data(), s, t[sd]);
      if (k.height_field) {
        if (occluders) height_field_step(k, s, t[sd], sd, side[sd].horizon);
        continue;
      }
      // Without an occluder nothing reads the step's intervals (visibility_mask_step).
      if (occluders) k.perspective ? step_intervals<true>(k, s, sd, t[sd]) : step_intervals<false>(k, s, sd, t[sd]);
      visibility_mask_step(k, f, t[sd], sd, occluders, side[sd], occupied);
    }
  }
  alignas(64) float visible[kLanes], horizon_cos[2][kLanes];
  for (int sd = 0; sd < 2; ++sd)
    for (int l = 0; l < kLanes; ++l)
      horizon_cos[sd][l] = k.height_field ? side[sd].horizon[l] : signed_sqrt(side[sd].horizon[l]);
  if (k.height_field)
    for (int l = 0; l < kLanes; ++l)
      visible[l] =
          height_field_integral(horizon_cos[0][l], horizon_cos[1][l], s.cos_n[l], s.sin_n[l], s.weight_total[l]);
  else
    visibility_mask_integrals(*k.sectors, occupied, s, visible);
  for (int l = 0; l < kLanes; ++l) {
    const float cp = horizon_cos[0][l], cm = horizon_cos[1][l];
    sums.visible[l] += s.pn_len[l] * visible[l];
    sums.open[l] += s.pn_len[l] * s.weight_total[l];
    add_slice_bent_normal(cp, cm, s, l, sums.bent_x[l], sums.bent_y[l], sums.bent_z[l]);
  }
}

// The group of pixels xi0 .. xi0 + kLanes - 1 of row y: its slices, then its sums into the
// row (0 where a pixel is not shaded).
void shade_group(const Constants& k, const Frame& f, TileRow& row, const RowPoints& points, int x0, int y, int xi0) {
  int any_taps = 0;
  for (int l = 0; l < kLanes; ++l) any_taps |= row.has_taps[xi0 + l];
  GroupSums sums;
  for (int i = 0; i < k.slices && any_taps; ++i) {
    SliceLanes s;
    s.compute(k, row, points, i, xi0);
    shade_slice(k, f, row, s, x0, y, xi0, i, sums);
  }
  for (int l = 0; l < kLanes; ++l) {
    const int xi = xi0 + l;
    const bool shaded = row.state[xi] == kShaded;
    row.visible_sum[xi] = shaded ? sums.visible[l] : 0.0f;
    row.open_sum[xi] = shaded ? sums.open[l] : 0.0f;
    row.bent_x[xi] = shaded ? sums.bent_x[l] : 0.0f;
    row.bent_y[xi] = shaded ? sums.bent_y[l] : 0.0f;
    row.bent_z[xi] = shaded ? sums.bent_z[l] : 0.0f;
  }
}
// A shaded pixel's AO from its estimate, with the multi-bounce approximation when the frame
// has an albedo.
inline float shaded_ao(float estimate, const cv::Vec3f* albedo) {
  return albedo ? std::min(multibounce(estimate, albedo_luminance(*albedo)), 1.0f) : estimate;
}

// The sums pooled slices read (Constants::pool_slices): each texel's visible and open
// measure (0 where it is not shaded) over `region`, the roi and a ring of one texel around
// it within the grid.
struct PoolSums {
  cv::Rect region;
  cv::Mat visible, open;  // CV_32FC1, region-sized
};

// The outputs of pixels x0 .. x1 - 1 of row y from their sums, where they lie in the roi,
// and the sums into `pool` when the slices are pooled (no branches: the loops vectorise).
// Background: AO 1 and no bent normal; no taps: AO 1 and the normal.
inline void finish_row(const Constants& k, const AoInputs& in, AoOutput& out, const cv::Rect& roi, int x0, int x1,
                       int y, const TileRow& row, PoolSums* pool) {
  if (pool) {
    float* visible = pool->visible.ptr<float>(y - pool->region.y) + (x0 - pool->region.x);
    float* open = pool->open.ptr<float>(y - pool->region.y) + (x0 - pool->region.x);
    for (int xi = 0; xi < x1 - x0; ++xi) {
      const bool shaded = row.state[xi] == kShaded;
      visible[xi] = shaded ? row.visible_sum[xi] : 0.0f;
      open[xi] = shaded ? row.open_sum[xi] : 0.0f;
    }
  }
  if (y < roi.y || y >= roi.y + roi.height) return;
  const int lo = std::max(x0, roi.x), hi = std::min(x1, roi.x + roi.width);
  const cv::Vec3f* normal_row = in.normal_view.ptr<cv::Vec3f>(y);
  const cv::Vec3f* albedo_row = k.multibounce ? in.albedo->ptr<cv::Vec3f>(y) : nullptr;
  float* ao_row = out.ao.ptr<float>(y);
  cv::Vec3f* bent_row = out.bent_normal_view.ptr<cv::Vec3f>(y);
  for (int x = lo; x < hi; ++x) {
    const int xi = x - x0;
    const bool shaded = row.state[xi] == kShaded;
    const float visible_sum = row.visible_sum[xi], open_sum = row.open_sum[xi];
    float ao = open_sum > 0.0f ? std::clamp(visible_sum / open_sum, 0.0f, 1.0f) : 1.0f;
    ao_row[x] = shaded ? ao : 1.0f;
  }
  if (k.multibounce)
    for (int x = lo; x < hi; ++x)
      if (row.state[x - x0] == kShaded) ao_row[x] = shaded_ao(ao_row[x], &albedo_row[x]);
  for (int x = lo; x < hi; ++x) {
    const int xi = x - x0;
    const uint8_t state = row.state[xi];
    const glm::vec3 bent(row.bent_x[xi], row.bent_y[xi], row.bent_z[xi]);
    const glm::vec3 normal(normal_row[x][0], normal_row[x][1], normal_row[x][2]);
    const float bent_len = glm::length(bent);
    glm::vec3 bn = bent_len > 1e-12f ? bent / bent_len : normal;
    bn = state == kShaded ? bn : state == kNoTaps ? normal : glm::vec3(0.0f);
    bent_row[x] = cv::Vec3f(bn.x, bn.y, bn.z);
  }
}

// Row y's pixels x0 .. x1 - 1, and the lanes after them up to a whole group (no taps):
// their tap patterns and points, before the row is shaded. A group's slice bases are
// computed at its slice (SliceLanes::compute) and its taps' texel indices at their step
// (group_step_indices): no row of either to hold in the first-level cache.
void plan_row(const Constants& k, const Frame& f, int x0, int x1, int y, TileRow& row, RowPoints& points) {
  const int n = x1 - x0, row_lanes = group_lanes(n);
  pixel_taps(k, f.in, x0, n, y, row);
  for (int xi = n; xi < row_lanes; ++xi) {
    row.has_taps[xi] = 0;
    row.spacing_px[xi] = row.step_noise[xi] = row.rot_s[xi] = 0.0f;
    row.level_cap[xi] = 0;
    row.rot_c[xi] = 1.0f;
    row.state[xi] = kBackground;
  }
  for (int xi = 0; xi < n; ++xi) points.set(size_t(xi), pixel_point(k, f, x0 + xi, y));
  for (int xi = n; xi < row_lanes; ++xi) points.set(size_t(xi), PixelPoint{});
}

// The tile [x0, x1) x [y0, y1), row by row: a row is planned (plan_row), then shaded a
// group of kLanes pixels at a time, each group's taps step by step.
inline void shade_tile(const Constants& k, const Frame& f, AoOutput& out, const cv::Rect& roi, PoolSums* pool,
                       int x0, int x1, int y0, int y1) {
  TileRow row;
  RowPoints points;
  const int row_lanes = group_lanes(x1 - x0);
  for (int y = y0; y < y1; ++y) {
    plan_row(k, f, x0, x1, y, row, points);
    for (int xi0 = 0; xi0 < row_lanes; xi0 += kLanes) shade_group(k, f, row, points, x0, y, xi0);
    finish_row(k, f.in, out, roi, x0, x1, y, row, pool);
  }
}

// Depth difference, relative to the pixel's, within which a neighbour's sums are pooled as
// of its surface: the upsample's tolerance (half_resolution.cpp), which keeps a surface
// behind a silhouette out.
constexpr float kPoolDepthFraction = 0.05f;

// Whether a neighbour counts in R (header, pooled slices): on the pixel's surface, within
// kPoolDepthFraction of its depth (an infinite background depth never is). R sets only the
// estimate's variance, not its expectation: the normals' weight as well (the upsample's
// max(0, n . n')^4) changed the ten shared frames' MAE by 1e-5.
[[gnu::always_inline]] inline bool pooled(float depth, float depth_k) {
  return std::abs(depth_k - depth) <= kPoolDepthFraction * depth;
}

// Pixel x of row y: the sums of its 3x3 texels that count (`pooled`) and lie in the pool's
// region, in row-major order (rows ny0 .. ny1), into visible and open; for the pixels of a
// roi edge on the frame's and those left after pooled_sums' vectors.
void pooled_sums_at(const AoInputs& in, const PoolSums& pool, int y, int ny0, int ny1, int x, float& visible,
                    float& open) {
  const float depth = in.depth_view.ptr<float>(y)[x];
  const int nx0 = std::max(x - 1, pool.region.x), nx1 = std::min(x + 1, pool.region.x + pool.region.width - 1);
  visible = open = 0.0f;
  for (int ny = ny0; ny <= ny1; ++ny) {
    const float* depth_k = in.depth_view.ptr<float>(ny);
    const float* visible_k = pool.visible.ptr<float>(ny - pool.region.y) - pool.region.x;
    const float* open_k = pool.open.ptr<float>(ny - pool.region.y) - pool.region.x;
    for (int nx = nx0; nx <= nx1; ++nx) {
      const bool near = pooled(depth, depth_k[nx]);
      visible += near ? visible_k[nx] : 0.0f;
      open += near ? open_k[nx] : 0.0f;
    }
  }
}

// Pixels [x0, x1) of row y, each with its 3 texel columns in the pool's region: their sums
// as pooled_sums_at's, into visible[x] and open[x], a vector of pixels at a time by the same
// operations in the same order (the same bits); the rest by pooled_sums_at.
void pooled_sums(const AoInputs& in, const PoolSums& pool, int y, int ny0, int ny1, int x0, int x1, float* visible,
                 float* open) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::ScalableTag<float> d;
  using V = hn::Vec<decltype(d)>;
  const int lanes = int(hn::Lanes(d));
  const float* depth = in.depth_view.ptr<float>(y);
  const V fraction = hn::Set(d, kPoolDepthFraction), zero = hn::Zero(d);
  int x = x0;
  for (; x + lanes <= x1; x += lanes) {
    const V depth_x = hn::LoadU(d, depth + x);
    const V tolerance = hn::Mul(fraction, depth_x);
    V v_sum = zero, o_sum = zero;
    for (int ny = ny0; ny <= ny1; ++ny) {
      const float* depth_k = in.depth_view.ptr<float>(ny);
      const float* visible_k = pool.visible.ptr<float>(ny - pool.region.y) - pool.region.x;
      const float* open_k = pool.open.ptr<float>(ny - pool.region.y) - pool.region.x;
      for (int nx = x - 1; nx <= x + 1; ++nx) {
        const auto near = hn::Le(hn::Abs(hn::Sub(hn::LoadU(d, depth_k + nx), depth_x)), tolerance);
        v_sum = hn::Add(v_sum, hn::IfThenElseZero(near, hn::LoadU(d, visible_k + nx)));
        o_sum = hn::Add(o_sum, hn::IfThenElseZero(near, hn::LoadU(d, open_k + nx)));
      }
    }
    hn::StoreU(v_sum, d, visible + x);
    hn::StoreU(o_sum, d, open + x);
  }
  for (; x < x1; ++x) pooled_sums_at(in, pool, y, ny0, ny1, x, visible[x], open[x]);
}

// Row y of the roi from pooled slices (header): R + (v - R o) / slices for each pixel with
// an open measure (which R's sums hold: a pixel counts itself), over the ratio finish_row
// wrote. `sums`: scratch of 2 x the roi's width.
void pool_row(const Constants& k, const AoInputs& in, const PoolSums& pool, AoOutput& out, const cv::Rect& roi, int y,
              float* sums) {
  const cv::Rect& r = pool.region;
  const int ny0 = std::max(y - 1, r.y), ny1 = std::min(y + 1, r.y + r.height - 1);
  const int x0 = roi.x, x1 = roi.x + roi.width;
  // The pixels whose three columns lie in the region: all but a roi edge on the frame's.
  const int inner0 = std::max(x0, r.x + 1), inner1 = std::max(inner0, std::min(x1, r.x + r.width - 1));
  float* visible = sums - x0;
  float* open = sums + roi.width - x0;
  pooled_sums(in, pool, y, ny0, ny1, inner0, inner1, visible, open);
  for (int x = x0; x < inner0; ++x) pooled_sums_at(in, pool, y, ny0, ny1, x, visible[x], open[x]);
  for (int x = inner1; x < x1; ++x) pooled_sums_at(in, pool, y, ny0, ny1, x, visible[x], open[x]);
  const float* own_visible = pool.visible.ptr<float>(y - r.y) - r.x;
  const float* own_open = pool.open.ptr<float>(y - r.y) - r.x;
  const float inv_slices = 1.0f / float(k.slices);
  float* ao_row = out.ao.ptr<float>(y);
  for (int x = x0; x < x1; ++x) {
    const float ratio = visible[x] / open[x];  // unused where the pixel has no open measure
    const float estimate = std::clamp(ratio + (own_visible[x] - ratio * own_open[x]) * inv_slices, 0.0f, 1.0f);
    ao_row[x] = own_open[x] > 0.0f ? estimate : ao_row[x];
  }
  if (k.multibounce) {
    const cv::Vec3f* albedo_row = in.albedo->ptr<cv::Vec3f>(y);
    for (int x = x0; x < x1; ++x)
      if (own_open[x] > 0.0f) ao_row[x] = shaded_ao(ao_row[x], &albedo_row[x]);
  }
}

// The roi's AO from pooled slices, row by row (pool_row).
void pool_slices(const Constants& k, const AoInputs& in, const PoolSums& pool, AoOutput& out, const cv::Rect& roi,
                 int nthreads) {
  parallel_rows(
      cv::Range(roi.y, roi.y + roi.height), nthreads,
      [&](const cv::Range& rows) {
        std::vector<float> sums(2 * size_t(roi.width));
        for (int y = rows.start; y < rows.end; ++y) pool_row(k, in, pool, out, roi, y, sums.data());
      },
      kTileHeightPx);
}

}  // namespace

void ao_gtao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
             int nthreads) {
  const Constants k(in, s);
  // Texel indices are 32-bit, and so are the texels' float offsets (gather_texels).
  CV_Assert(k.grid.texels <= int64_t(INT32_MAX / 4));
  Frame f{in, {}, {}};
  build_texels(in, back_layer(in, k), k.thickness_world, k.grid, f.texels, f.planes, nthreads);
  // Pooled slices read a ring of one texel around the roi too, shaded with it, so that the
  // roi's pixels are the whole frame's.
  const cv::Rect region = k.pool_slices ? (roi - cv::Point(1, 1) + cv::Size(2, 2)) &
                                              cv::Rect(0, 0, in.depth_view.cols, in.depth_view.rows)
                                        : roi;
  PoolSums pool{region, {}, {}};
  if (k.pool_slices) {
    pool.visible.create(region.size(), CV_32FC1);
    pool.open.create(region.size(), CV_32FC1);
  }
  // Tiles of kTileWidthPx x kTileHeightPx pixels: a pixel's taps land anywhere within its
  // radius, so the texels a tile reads are its footprint grown by the radius, which stays
  // in cache while the tile runs; row by row, the band of rows within the radius of a
  // whole row would not.
  parallel_rows(
      cv::Range(region.y, region.y + region.height), nthreads,
      [&](const cv::Range& rows) {
        for (int y0 = rows.start; y0 < rows.end; y0 += kTileHeightPx) {
          const int y1 = std::min(y0 + kTileHeightPx, rows.end);
          for (int x0 = region.x; x0 < region.x + region.width; x0 += kTileWidthPx)
            shade_tile(k, f, out, roi, k.pool_slices ? &pool : nullptr, x0,
                       std::min(x0 + kTileWidthPx, region.x + region.width), y0, y1);
        }
      },
      kTileHeightPx);
  if (k.pool_slices) pool_slices(k, in, pool, out, roi, nthreads);
}

}  // namespace ssdo::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::detail {

SSDO_AO_METHOD_DISPATCH(ao_gtao)

}  // namespace ssdo::detail
#endif  // HWY_ONCE
