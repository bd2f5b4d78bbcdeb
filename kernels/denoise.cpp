// The cross (joint) bilateral filter of Tomasi & Manduchi 1998, "Bilateral filtering for
// gray and color images", with the range kernel on the guides instead of the filtered
// image: a tap's weight is the spatial Gaussian times edge-stopping weights on depth and
// normal (denoise.h). Separable: a horizontal pass, then a vertical pass over its result.
//
// Layout. The frame is cut into tiles; per tile the guides are copied into planes over the
// tile and its halo, and the source channels into a row buffer, a row at a time just before
// the horizontal pass filters it, with the normal zeroed where the mask is 0 or outside the
// image (the normal lobe then weighs those taps 0 and the terms they add are exact zeros)
// and the source zeroed there (no masked value is read into a sum). Each
// pass is, per tile row, a weight computation and an accumulation over the taps k for a
// vector of pixels at once (Highway: the same source for every instruction set).
//
// A tap's weight is symmetric in the pair of pixels (a, b): the normal lobe's n_a . n_b
// and n_b . n_a are the same products summed in the same order, the depth weight's
// |d_b - d_a| (1 / d_a + 1 / d_b) is the same either way, and g(-k) = g(k), so the same
// bits from either end. Each pass computes the weight of every pair at offset k = 1 .. T
// once (pair_weights), and tap -k of a pixel reads the weight that tap +k of the pixel k
// before it computed: half the weights, and the tap loop itself only sums.
#include "kernels/denoise.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/denoise.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/cache_control.h>
#include <hwy/highway.h>

#include "kernels/settings_check.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "core/parallel.h"
#include "core/sanitizer_build.h"
#include "kernels/integer_power.h"
#include "kernels/mask_lanes.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

constexpr int kMaxRadiusPx = 32;

// A row's pixels in one vector, as many as the target holds (8 on AVX2, 16 on AVX-512, 4
// on NEON, 1 on the scalar baseline), so that a pass keeps its per-channel sums in
// registers across the taps. Every operation below is lane by lane, so the width changes
// the speed, not the bits.
using FloatLanes = hn::ScalableTag<float>;
using Lanes = hn::Vec<FloatLanes>;
constexpr int kMaxLanes = int(hn::MaxLanes(FloatLanes()));

inline int lane_count() { return int(hn::Lanes(FloatLanes())); }

inline Lanes broadcast(float x) { return hn::Set(FloatLanes(), x); }

// std::max(0.0f, x) lane by lane: x where 0 < x, else +0 (NaN -> 0, as std::max). hn::Max
// leaves NaN and the sign of zero to the instruction set: on x86's vector targets it is
// maxps / vmaxps(a, b), which returns b unless a > b, NaN and either zero included (Intel
// SDM, MAXPS): exactly std::max(0, x) with b = 0, in one instruction instead of two.
inline Lanes max0(Lanes x) {
#if HWY_ARCH_X86 && HWY_TARGET != HWY_SCALAR && HWY_TARGET != HWY_EMU128
  return hn::Max(x, hn::Zero(FloatLanes()));
#else
  return hn::IfThenElseZero(hn::Gt(x, hn::Zero(FloatLanes())), x);
#endif
}

// c^P by squaring, unrolled at compile time so that the tap loop stays branch-free.
template <unsigned P>
inline Lanes ipow(Lanes c) {
  if constexpr (P == 0) {
    return broadcast(1.0f);
  } else if constexpr (P == 1) {
    return c;
  } else {
    const Lanes h = ipow<P / 2>(c);
    if constexpr (P % 2 == 0) return hn::Mul(h, h);
    else return hn::Mul(hn::Mul(h, h), c);
  }
}

// The normal lobe max(0, n . n_tap)^normal_power of the range weight, applied to
// c = max(0, n . n_tap). The default power by compile-time squaring: a runtime exponent
// (or std::pow) per tap costs more than the rest of the weight together.
struct DefaultLobe {
  static constexpr unsigned kPower = 16;
  Lanes operator()(Lanes c) const { return ipow<kPower>(c); }
};
static_assert(DenoiseSettings{}.normal_power == float(DefaultLobe::kPower));

// Any power in [0, 256]: integers by squaring from the most significant bit
// (integer_power: the association of ipow, so the same bits as ipow<P>; Highway's vectors
// have its *), other powers by std::pow. 0 where c = 0: masked taps have normal 0, and
// c^0 = 1 would count them.
struct PowerLobe {
  float power;
  explicit PowerLobe(float p) : power(p) {}
  Lanes operator()(Lanes c) const {
    const FloatLanes d;
    return hn::IfThenElseZero(hn::Gt(c, hn::Zero(d)), power_of(d, c, power));
  }
};

// The taps per side T of a pass, as the tap loops read it: a compile-time constant for the
// default footprint (DefaultTaps: radius 4 at spacing 1, and its half-grid scaling, radius 8
// at spacing 2), so that the loops unroll with no branch per tap and constant plane offsets;
// the settings' value, an int, otherwise (a loop, not unrolled: one copy of the code for
// every other footprint). The same taps in the same order either way: the same bits.
using DefaultTaps = std::integral_constant<int, 4>;
static_assert(DenoiseSettings{}.radius_px / DenoiseSettings{}.tap_spacing_px == DefaultTaps::value);

// f(k) for k = from .. T in order. (GCC unrolls the fixed loop only with the bound a
// constant expression in the condition, not a call.) Not forced in a sanitizer build, where
// every load and check of the unrolled bodies (a row of up to 8 channels per tap) is
// instrumented: clang then spent three times as long on this file as without the unroll,
// for tests that do not time it. The same taps in the same order either way.
template <int kT, class F>
inline void for_each_tap(std::integral_constant<int, kT>, int from, const F& f) {
#ifndef SSDO_SANITIZER_BUILD
  HWY_UNROLL(2 * kMaxRadiusPx + 1)
#endif
  for (int k = from; k <= kT; ++k) f(k);
}
template <class F>
inline void for_each_tap(int taps, int from, const F& f) {
  for (int k = from; k <= taps; ++k) f(k);
}

// Tile of the filter, pixels: kTileRows x kTileCols outputs. With the halo of R rows and
// columns either side, every plane of a tile (depth, its scale, normal x/y/z, C horizontal
// results; the C source values and the pair weights are rows) is (64 + 2R) x (256 + 2R +
// kMaxLanes) floats, 81 KB at the default R = 4 on AVX-512 (92 KB at the half grid's R =
// 8): the passes run on planes in the second-level cache, and the frame's guides and
// source are read from memory once. The vertical pass's taps read 2R halo rows, which
// the horizontal pass computes for the first tile of a block of rows and each tile below
// keeps from the one above (copy_halo); 64 rows keep three channels' planes in a 2 MiB
// second-level cache (docs/performance.md, "The denoise's tiles 64 rows tall, its values a
// row at a time", "The denoise's halo rows computed once per block").
// The kMaxLanes columns past the halo let pair_weights run whole vectors past it (for
// nobody).
constexpr int kTileRows = 64;
constexpr int kTileCols = 256;
static_assert(kTileCols % kMaxLanes == 0, "a tile row is whole vectors");

// The most channels one pass filters with the same weights (AO and both SSDO terms are 7);
// more are filtered in several passes. The channels are independent, so how they are
// grouped changes the speed, not the values.
constexpr int kMaxPassChannels = 8;

// One channel of a pass: channel `offset` of *src (`stride` channels per pixel), written to
// the same channel of *dst.
struct Channel {
  const cv::Mat* src;
  cv::Mat* dst;
  int offset;
  int stride;
};

// What every tile of a call reads: the guides and the constants from the settings.
struct FilterConstants {
  const cv::Mat& depth_view;   // CV_32FC1 planar depth
  const cv::Mat& normal_view;  // CV_32FC3 unit view-space normal
  const cv::Mat& mask;         // CV_8UC1, 0 = not filtered and not read
  int width, height;           // the frame
  int taps;                    // T: taps k in [-T, T] per pass, k spacing pixels apart
  int spacing;                 // tap_spacing_px
  int radius;                  // R = T spacing: the pixels a pass reaches either side (the halo)
  float g[2 * kMaxRadiusPx + 1];  // the spatial Gaussian of tap k (at k spacing pixels), at k + T
  float half_inv_tol;          // 1 / (2 depth_tolerance_relative)
  int plane_stride;            // floats per plane row: kTileCols + 2R + kMaxLanes
  size_t plane;                // floats per plane: plane_stride x (kTileRows + 2R)

  FilterConstants(const cv::Mat& depth, const cv::Mat& normal, const cv::Mat& m, const DenoiseSettings& s)
      : depth_view(depth), normal_view(normal), mask(m), width(depth.cols), height(depth.rows),
        taps(s.radius_px / s.tap_spacing_px), spacing(s.tap_spacing_px), radius(taps * spacing), g{},
        half_inv_tol(0.5f / s.depth_tolerance_relative), plane_stride(kTileCols + 2 * radius + kMaxLanes),
        plane(size_t(plane_stride) * size_t(kTileRows + 2 * radius)) {
    for (int k = -taps; k <= taps; ++k) {
      const int d = k * spacing;
      g[k + taps] = std::exp(-0.5f * float(d * d) / (s.sigma_px * s.sigma_px));
    }
  }
};

// A tile: output rows [ya, yb), columns [xa, xb). Plane row j is image row ya - R + j,
// plane column i is image column xa - R + i.
struct Tile {
  int ya, yb, xa, xb;
  int width() const { return xb - xa; }
  // Columns each pass computes: whole vectors (the pixels past xb are computed and not
  // written; the planes' rows hold them).
  int lane_width() const { return (width() + lane_count() - 1) / lane_count() * lane_count(); }
};

// The planes of a tile in the per-thread scratch.
struct TilePlanes {
  float* depth;
  float* scale;       // 1 / (2 tol depth) (depth_scale), 0 where the depth is 0
  float* nx;
  float* ny;
  float* nz;
  float* value;       // C rows, plane_stride floats apart: the source channels of the plane row
                      // the horizontal pass filters (fill_row writes it just before)
  float* horizontal;  // C planes: the horizontal pass, tile columns only (no column halo)
  float* ring;        // the vertical pass's pair weights at taps 1 .. T (pair_weights) of its
                      // last R + 1 plane rows: T rings of R + 1 rows (ring_row)
  float* row_weight;  // T rows: the horizontal pass's, of the plane row it filters
  float* halo;        // the halo store (copy_halo) of every column of tiles, halo_column floats apart
  size_t halo_column;
};

// The guide planes of a tile: depth, its scale, normal x, y, z.
constexpr int kGuidePlanes = 5;

// The planes and rows of a tile for C channels, in this order at `scratch`: the guide
// planes, C value rows, C planes of horizontal results, T rings of R + 1 weight rows, T
// weight rows, then the halo store of `columns` columns of tiles (kGuidePlanes + C planes
// of 2R rows each); *floats receives how many floats they take (scratch may be null: the
// count only).
TilePlanes tile_planes(float* scratch, const FilterConstants& k, int channels, int columns,
                       size_t* floats = nullptr) {
  size_t at = 0;
  auto take = [&](size_t n) {
    float* q = scratch ? scratch + at : nullptr;
    at += n;
    return q;
  };
  const size_t plane = k.plane, row = size_t(k.plane_stride), c = size_t(channels), taps = size_t(k.taps);
  TilePlanes p;
  p.depth = take(plane);
  p.scale = take(plane);
  p.nx = take(plane);
  p.ny = take(plane);
  p.nz = take(plane);
  p.value = take(c * row);
  p.horizontal = take(c * plane);
  p.ring = take(taps * size_t(k.radius + 1) * row);
  p.row_weight = take(taps * row);
  p.halo_column = (kGuidePlanes + c) * size_t(2 * k.radius) * row;
  p.halo = take(size_t(columns) * p.halo_column);
  if (floats) *floats = at;
  return p;
}

// The thread's scratch for the tiles of every filter_channels (whatever its channels, lobe
// and taps: one buffer per thread, not one per instantiation), at least `floats` long; it
// grows once per thread to the largest call's size (never inside the pixel loops).
float* tile_scratch(size_t floats) {
  thread_local std::vector<float> buffer;
  if (buffer.size() < floats) buffer.resize(floats);
  return buffer.data();
}


// What fill_row reads of one image row: the mask, the guides and the C channels'
// values (channel c of pixel x at value[c][x * stride[c]]; stride 1 or 3).
template <int C>
struct SourceRow {
  const uint8_t* mask;
  const float* depth;
  const float* normal;  // x, y, z of each pixel
  const float* value[C];
  int stride[C];

  SourceRow(const FilterConstants& k, const Channel* ch, int y)
      : mask(k.mask.ptr<uint8_t>(y)), depth(k.depth_view.ptr<float>(y)), normal(k.normal_view.ptr<float>(y)) {
    for (int c = 0; c < C; ++c) {
      value[c] = ch[c].src->ptr<float>(y) + ch[c].offset;
      stride[c] = ch[c].stride;
    }
  }
};

// Where fill_row writes plane row j: the guides' rows in their planes (column 0 of each),
// the channels' values in the row buffer.
template <int C>
struct PlaneRow {
  float* depth;
  float* scale;
  float* nx;
  float* ny;
  float* nz;
  float* value[C];

  PlaneRow(const FilterConstants& k, const TilePlanes& p, int j) {
    const size_t row = size_t(j) * size_t(k.plane_stride);
    depth = p.depth + row, scale = p.scale + row, nx = p.nx + row, ny = p.ny + row, nz = p.nz + row;
    for (int c = 0; c < C; ++c) value[c] = p.value + size_t(c) * size_t(k.plane_stride);
  }
};

// Columns [from, to) of a plane row: 0 in every plane and value row.
template <int C>
void zero_columns(const PlaneRow<C>& r, int from, int to) {
  float* rows[kGuidePlanes + C] = {r.depth, r.scale, r.nx, r.ny, r.nz};
  for (int c = 0; c < C; ++c) rows[kGuidePlanes + c] = r.value[c];
  for (float* q : rows) std::fill(q + from, q + to, 0.0f);
}

// The depth weight's scale 1 / (2 tol d) of a pixel at depth d, once per pixel rather than
// per pair (a division).
inline float depth_scale(const FilterConstants& k, float depth) { return k.half_inv_tol / depth; }
inline Lanes depth_scale(const FilterConstants& k, Lanes depth) { return hn::Div(broadcast(k.half_inv_tol), depth); }

// Pixel x of a source row into column i of the plane row; 0 where the mask is 0.
template <int C>
inline void fill_pixel(const FilterConstants& k, const SourceRow<C>& s, int x, const PlaneRow<C>& r, int i) {
  const bool on = s.mask[x] != 0;
  r.depth[i] = on ? s.depth[x] : 0.0f;
  r.scale[i] = on ? depth_scale(k, s.depth[x]) : 0.0f;
  r.nx[i] = on ? s.normal[3 * x] : 0.0f;
  r.ny[i] = on ? s.normal[3 * x + 1] : 0.0f;
  r.nz[i] = on ? s.normal[3 * x + 2] : 0.0f;
  for (int c = 0; c < C; ++c) r.value[c][i] = on ? s.value[c][x * s.stride[c]] : 0.0f;
}

// The vector of pixels from x, as fill_pixel.
template <int C>
inline void fill_vector(const FilterConstants& k, const SourceRow<C>& s, int x, const PlaneRow<C>& r, int i) {
  const FloatLanes d;
  const hn::Mask<FloatLanes> on = foreground_lanes(s.mask + x);
  const Lanes depth = hn::LoadU(d, s.depth + x);
  hn::StoreU(hn::IfThenElseZero(on, depth), d, r.depth + i);
  hn::StoreU(hn::IfThenElseZero(on, depth_scale(k, depth)), d, r.scale + i);
  Lanes v[3];
  hn::LoadInterleaved3(d, s.normal + 3 * size_t(x), v[0], v[1], v[2]);
  hn::StoreU(hn::IfThenElseZero(on, v[0]), d, r.nx + i);
  hn::StoreU(hn::IfThenElseZero(on, v[1]), d, r.ny + i);
  hn::StoreU(hn::IfThenElseZero(on, v[2]), d, r.nz + i);
  for (int c = 0; c < C;) {
    if (s.stride[c] == 1) {
      hn::StoreU(hn::IfThenElseZero(on, hn::LoadU(d, s.value[c] + x)), d, r.value[c] + i);
      ++c;
      continue;
    }
    // value[c] points at the channel: the first of each three floats. Channels c, c + 1,
    // c + 2 of one image (AO's and the SSDO terms' layout) come from one de-interleave.
    hn::LoadInterleaved3(d, s.value[c] + 3 * size_t(x), v[0], v[1], v[2]);
    const bool whole = c + 2 < C && s.stride[c + 1] == 3 && s.stride[c + 2] == 3 && s.value[c + 1] == s.value[c] + 1 &&
                       s.value[c + 2] == s.value[c] + 2;
    for (int j = 0; j < (whole ? 3 : 1); ++j) hn::StoreU(hn::IfThenElseZero(on, v[j]), d, r.value[c + j] + i);
    c += whole ? 3 : 1;
  }
}

// Plane row j of the tile (image row ya - R + j) from the frame: the guides into their
// planes, the source channels into the row buffer; zeros outside the image and where the
// mask is 0.
template <int C>
void fill_row(const FilterConstants& k, const Channel* ch, const Tile& t, const TilePlanes& p, int j) {
  const int R = k.radius, columns = t.lane_width() + 2 * R, n = lane_count();
  // Plane column i is image column x0 + i; [first, end) are inside the image.
  const int x0 = t.xa - R, first = std::max(0, -x0), end = std::min(columns, k.width - x0);
  const int y = t.ya - R + j;
  const PlaneRow<C> r(k, p, j);
  if (y < 0 || y >= k.height) {
    zero_columns<C>(r, 0, columns);
    return;
  }
  const SourceRow<C> s(k, ch, y);
  zero_columns<C>(r, 0, first);
  // Vectors stop a pixel before the image's right edge: a 3-channel source's channel
  // c > 0 is loaded as whole pixels from that channel on, c floats past the last pixel.
  int i = first;
  for (; i + n < end; i += n) fill_vector(k, s, x0 + i, r, i);
  for (; i < end; ++i) fill_pixel(k, s, x0 + i, r, i);
  zero_columns<C>(r, end, columns);
}

// The normal lobe of the range weight: lobe(max(0, n . n_tap)).
template <class Lobe>
inline Lanes normal_lobe(Lanes nx, Lanes ny, Lanes nz, Lanes tap_nx, Lanes tap_ny, Lanes tap_nz, const Lobe& lobe) {
  return lobe(max0(hn::Add(hn::Add(hn::Mul(nx, tap_nx), hn::Mul(ny, tap_ny)), hn::Mul(nz, tap_nz))));
}

// The weight of the pairs (a, a + k step) of a vector of pixels a: the hard-cut linear
// depth weight max(0, 1 - |d_b - d_a| (scale_a + scale_b)) (scale = 1 / (2 tol d):
// the depth difference relative to the harmonic mean of the two depths) times g(k) times
// the normal lobe.
inline Lanes pair_weight(Lanes depth, Lanes scale, Lanes tap_depth, Lanes tap_scale, Lanes g_lobe) {
  const Lanes wd =
      max0(hn::Sub(broadcast(1.0f), hn::Mul(hn::Abs(hn::Sub(tap_depth, depth)), hn::Add(scale, tap_scale))));
  return hn::Mul(wd, g_lobe);
}

// The pair weights at taps k = 1 .. T (step apart) of guide offsets [from, to) (extended to
// whole vectors), the weight of pair (pos, pos + k step) at dst[k - 1][pos - from].
template <class Lobe, class Taps>
void pair_weights(const FilterConstants& k, const TilePlanes& p, size_t from, size_t to, ptrdiff_t step, Taps taps,
                  float* const* dst, const Lobe& lobe) {
  const FloatLanes d;
  const size_t n = size_t(lane_count());
  for (size_t pos = from; pos < to; pos += n) {
    const Lanes nx = hn::LoadU(d, p.nx + pos), ny = hn::LoadU(d, p.ny + pos), nz = hn::LoadU(d, p.nz + pos);
    const Lanes depth = hn::LoadU(d, p.depth + pos), scale = hn::LoadU(d, p.scale + pos);
    for_each_tap(taps, 1, [&](int j) {
      const size_t tap = size_t(ptrdiff_t(pos) + j * step);
      const Lanes g_lobe = hn::Mul(broadcast(k.g[int(taps) + j]),
                                   normal_lobe(nx, ny, nz, hn::LoadU(d, p.nx + tap), hn::LoadU(d, p.ny + tap),
                                               hn::LoadU(d, p.nz + tap), lobe));
      const Lanes w = pair_weight(depth, scale, hn::LoadU(d, p.depth + tap), hn::LoadU(d, p.scale + tap), g_lobe);
      hn::StoreU(w, d, dst[j - 1] + (pos - from));
    });
  }
}

// The weights of a tile row's taps, by the row's pixel i: tap +k at plus[k - 1][i] (the
// pixel's pair with the pixel k taps after it), tap -k at minus[k - 1][i] (the pair of the
// pixel k taps before it with this one: the same weight, computed once).
struct RowWeights {
  const float* plus[kMaxRadiusPx];
  const float* minus[kMaxRadiusPx];
};

// One pass over a tile row: out[c][i] = sum_k w_k v_c,k / sum_k w_k for the tile row's
// pixels i in [0, lane_width). The centre's depth at plane offset `centre` + i; tap k of
// channel c at values + c * value_plane + k * step + i (step: a tap's spacing along the
// pass); the weights of taps k != 0 in `weights`. A foreground centre (depth > 0) weighs 1
// (g(0) = 1, depth weight 1, and the lobe of a unit normal with itself), so its weight sum
// is never 0; a masked centre (depth and normal 0) weighs itself and every tap 0, and its
// outputs are 0, not the 0 / 0 of the sums.
template <int C, class Taps>
void filter_row(const TilePlanes& p, const Tile& t, size_t centre, ptrdiff_t step, const float* values,
                size_t value_plane, float* const* out, Taps taps, const RowWeights& weights) {
  const FloatLanes d;
  const int T = taps, width = t.lane_width(), n = lane_count();
  for (int i = 0; i < width; i += n) {
    const Lanes self = hn::IfThenElseZero(hn::Gt(hn::LoadU(d, p.depth + centre + size_t(i)), hn::Zero(d)),
                                          broadcast(1.0f));
    Lanes sum[C], wsum = hn::Zero(d);
    for (int c = 0; c < C; ++c) sum[c] = hn::Zero(d);
    for_each_tap(taps, -T, [&](int tap) {
      const ptrdiff_t off = tap * step + i;
      const Lanes w = tap == 0  ? self
                      : tap > 0 ? hn::LoadU(d, weights.plus[tap - 1] + i)
                                : hn::LoadU(d, weights.minus[-tap - 1] + i);
      for (int c = 0; c < C; ++c) sum[c] = hn::Add(sum[c], hn::Mul(w, hn::LoadU(d, values + c * value_plane + off)));
      wsum = hn::Add(wsum, w);
    });
    const Lanes inv = hn::Div(broadcast(1.0f), wsum);
    const hn::Mask<FloatLanes> weighed = hn::Gt(wsum, hn::Zero(d));
    for (int c = 0; c < C; ++c) hn::StoreU(hn::IfThenElseZero(weighed, hn::Mul(sum[c], inv)), d, out[c] + i);
  }
}

// Pass 1 (horizontal) on the tile's plane rows from `first` on (the rows before it were
// kept from the tile above: copy_halo), each row filled from the frame just before it is
// filtered (its values read from the row buffer while in the first-level cache; the guide
// planes stay for pass 2). Masked pixels (filter_row) and rows outside the image get 0
// (their normal is 0, so pass 2 weighs them 0 anyway; no NaN is read).
template <int C, class Lobe, class Taps>
void horizontal_pass(const FilterConstants& k, const Channel* ch, const TilePlanes& p, const Tile& t, int first,
                     const Lobe& lobe, Taps taps) {
  const int R = k.radius;
  // Pairs (x, x + k spacing) of a row from column 0, tap k's in row buffer k - 1: centres
  // from column R, taps -k from column R - k spacing.
  float* dst[kMaxRadiusPx];
  RowWeights weights;
  for (int tap = 1; tap <= int(taps); ++tap) {
    dst[tap - 1] = p.row_weight + size_t(tap - 1) * size_t(k.plane_stride);
    weights.plus[tap - 1] = dst[tap - 1] + R;
    weights.minus[tap - 1] = dst[tap - 1] + R - tap * k.spacing;
  }
  for (int j = first; j < (t.yb - t.ya) + 2 * R; ++j) {
    fill_row<C>(k, ch, t, p, j);
    const int y = t.ya - R + j;
    const size_t row = size_t(j) * size_t(k.plane_stride);
    float* out[C];
    for (int c = 0; c < C; ++c) out[c] = p.horizontal + c * k.plane + row;
    if (y < 0 || y >= k.height) {
      for (int c = 0; c < C; ++c)
        for (int i = 0; i < t.lane_width(); ++i) out[c][i] = 0.0f;
      continue;
    }
    pair_weights(k, p, row, row + size_t(t.lane_width() + R), k.spacing, taps, dst, lobe);
    filter_row<C>(p, t, row + size_t(R), k.spacing, p.value + R, size_t(k.plane_stride), out, taps, weights);
  }
}

// The outputs' rows are written with non-temporal stores (hn::Stream) where they are
// aligned to a vector: a frame's outputs are larger than the caches, so a plain store first
// reads each line into the cache (a read for ownership) only for it to be evicted unread:
// about a fifth of the filter's memory traffic with three channels. Stream stores are
// ordered by hwy::FlushStream at the end of each thread's strip, before the caller reads
// them. Where the outputs fit the caches (640 x 360) the streams measured no slower.
inline bool streams(const float* out) {
  return reinterpret_cast<uintptr_t>(out) % (size_t(lane_count()) * sizeof(float)) == 0;
}

// Columns [0, width) of one output row of an N-channel image (N = 1 or 3) whose channels
// are result[0 .. N): the filtered value where the mask is set, the source where not;
// whole pixels a vector at a time (three strided scalar stores per pixel took a third of
// the vertical pass).
template <int N>
inline void write_pixels(const uint8_t* m, const float* in, float* out, int width, const float* const* result) {
  static_assert(N == 1 || N == 3);
  const FloatLanes d;
  const int n = lane_count();
  const bool stream = streams(out);
  int i = 0;
  for (; i + n <= width; i += n) {
    const hn::Mask<FloatLanes> on = foreground_lanes(m + i);
    Lanes v[N];
    for (int c = 0; c < N; ++c) v[c] = hn::LoadU(d, result[c] + i);
    if (!hn::AllTrue(d, on)) {  // most vectors are all foreground: the source is not read
      Lanes source[N];
      if constexpr (N == 1)
        source[0] = hn::LoadU(d, in + i);
      else
        hn::LoadInterleaved3(d, in + 3 * size_t(i), source[0], source[1], source[2]);
      for (int c = 0; c < N; ++c) v[c] = hn::IfThenElse(on, v[c], source[c]);
    }
    float* at = out + size_t(N) * size_t(i);
    if constexpr (N == 1) {
      if (stream)
        hn::Stream(v[0], d, at);
      else
        hn::StoreU(v[0], d, at);
    } else if (stream) {  // interleaved in the first-level cache, then streamed out
      alignas(64) float pixels[3 * kMaxLanes];
      hn::StoreInterleaved3(v[0], v[1], v[2], d, pixels);
      for (int c = 0; c < 3; ++c) hn::Stream(hn::Load(d, pixels + c * n), d, at + c * n);
    } else {
      hn::StoreInterleaved3(v[0], v[1], v[2], d, at);
    }
  }
  for (; i < width; ++i)
    for (int c = 0; c < N; ++c) out[N * i + c] = m[i] ? result[c][i] : in[N * i + c];
}

// Output row y of the tile from the pass's results: the filtered value where the mask is
// set, the source where not.
template <int C>
void write_row(const Channel* ch, const uint8_t* m, const Tile& t, int y, const float (*result)[kTileCols]) {
  for (int c = 0; c < C;) {
    const float* in = ch[c].src->ptr<float>(y) + ch[c].offset;
    float* out = ch[c].dst->ptr<float>(y) + ch[c].offset;
    const int stride = ch[c].stride;
    if (stride == 1) {  // a 1-channel image
      const float* channel = result[c];
      write_pixels<1>(m + t.xa, in + t.xa, out + t.xa, t.width(), &channel);
      ++c;
      continue;
    }
    if (stride == 3 && ch[c].offset == 0 && c + 2 < C && ch[c + 2].src == ch[c].src) {  // a whole image
      const float* channels[3] = {result[c], result[c + 1], result[c + 2]};
      write_pixels<3>(m + t.xa, in + 3 * t.xa, out + 3 * t.xa, t.width(), channels);
      c += 3;
      continue;
    }
    for (int i = 0; i < t.width(); ++i) {
      const int x = t.xa + i;
      out[x * stride] = m[x] ? result[c][i] : in[x * stride];
    }
    ++c;
  }
}

// Row r of the vertical pass's ring of tap k's pair weights (plane row r of the tile: the
// pairs (r, r + k spacing) of its columns from column R).
inline float* ring_row(const FilterConstants& k, const TilePlanes& p, int tap, int r) {
  const int rows = k.radius + 1;
  return p.ring + (size_t(tap - 1) * size_t(rows) + size_t(r % rows)) * size_t(k.plane_stride);
}

// Pass 2 (vertical) over the horizontal results, on the tile's rows, into the outputs;
// masked pixels copy the source. A row's pair weights are computed just before it is
// filtered, into rings of the last R + 1 rows (the pairs its taps -k read are those of the
// rows k spacing above it), which stay in the first-level cache.
template <int C, class Lobe, class Taps>
void vertical_pass(const FilterConstants& k, const Channel* ch, const TilePlanes& p, const Tile& t,
                   const Lobe& lobe, Taps taps) {
  const int R = k.radius;
  const size_t stride = size_t(k.plane_stride);
  const ptrdiff_t tap_step = ptrdiff_t(k.spacing) * k.plane_stride;
  auto pairs_of_row = [&](int r) {
    float* dst[kMaxRadiusPx];
    for (int j = 1; j <= int(taps); ++j) dst[j - 1] = ring_row(k, p, j, r);
    const size_t first = size_t(r) * stride + size_t(R);
    pair_weights(k, p, first, first + size_t(t.lane_width()), tap_step, taps, dst, lobe);
  };
  for (int r = 0; r < R; ++r) pairs_of_row(r);
  for (int y = t.ya; y < t.yb; ++y) {
    const int r = y - t.ya + R;
    pairs_of_row(r);
    RowWeights weights;
    for (int j = 1; j <= int(taps); ++j) {
      weights.plus[j - 1] = ring_row(k, p, j, r);
      weights.minus[j - 1] = ring_row(k, p, j, r - j * k.spacing);
    }
    const size_t row = size_t(r) * stride;
    float result[C][kTileCols];
    float* to[C];
    for (int c = 0; c < C; ++c) to[c] = result[c];
    filter_row<C>(p, t, row + size_t(R), tap_step, p.horizontal + row, k.plane, to, taps, weights);
    write_row<C>(ch, k.mask.ptr<uint8_t>(y), t, y, result);
  }
}

// The plane rows a tile shares with the tile below it in the same columns: the tile below
// reads, as its plane rows [0, 2R), the image rows yb - R .. yb + R - 1 that the tile has
// in its plane rows [h, h + 2R) (h: its height), guides and horizontal results. A thread
// keeps them per column of tiles in a halo store (kGuidePlanes + C planes of 2R rows
// each), so that the horizontal pass of the tile below starts at row 2R instead of
// computing them again.
// Plane rows [row, row + 2R) of the kept planes into `store` (to_store), or back from it.
template <int C>
void copy_halo(const FilterConstants& k, const TilePlanes& p, int row, float* store, bool to_store) {
  const size_t rows = size_t(2 * k.radius) * size_t(k.plane_stride);
  const size_t at = size_t(row) * size_t(k.plane_stride);
  float* planes[kGuidePlanes + C] = {p.depth, p.scale, p.nx, p.ny, p.nz};
  for (int c = 0; c < C; ++c) planes[kGuidePlanes + c] = p.horizontal + size_t(c) * k.plane;
  for (int q = 0; q < kGuidePlanes + C; ++q, store += rows) {
    if (to_store)
      std::copy(planes[q] + at, planes[q] + at + rows, store);
    else
      std::copy(store, store + rows, planes[q] + at);
  }
}

// The filter of C channels with one set of weights, over the roi r. Each thread takes
// blocks of rows (parallel_row_blocks) and filters a block a row of tiles at a time (in
// the frame's memory order), each tile starting from the halo rows the tile above left in
// the halo store: the horizontal pass computes a block's 2R halo rows once, not once per
// row of tiles. Every pixel's sums are the same whatever the blocks and tiles: the same
// bits.
template <int C, class Lobe, class Taps>
void filter_channels(const FilterConstants& k, const Channel* ch, const cv::Rect& r, int nthreads,
                     const Lobe& lobe, Taps taps) {
  const int columns = (r.width + kTileCols - 1) / kTileCols;
  size_t scratch_floats = 0;
  tile_planes(nullptr, k, C, columns, &scratch_floats);
  static_assert(kTileRows >= 2 * kMaxRadiusPx, "a tile's halo rows below do not overlap its top ones");
  parallel_row_blocks(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    const TilePlanes planes = tile_planes(tile_scratch(scratch_floats), k, C, columns);
    for (int ya = rows.start; ya < rows.end; ya += kTileRows) {
      const int yb = std::min(ya + kTileRows, rows.end);
      for (int i = 0; i < columns; ++i) {
        const int xa = r.x + i * kTileCols;
        const Tile t{ya, yb, xa, std::min(xa + kTileCols, r.x + r.width)};
        float* const store = planes.halo + size_t(i) * planes.halo_column;
        if (ya > rows.start) copy_halo<C>(k, planes, 0, store, false);
        horizontal_pass<C>(k, ch, planes, t, ya > rows.start ? 2 * k.radius : 0, lobe, taps);
        vertical_pass<C>(k, ch, planes, t, lobe, taps);
        if (yb < rows.end) copy_halo<C>(k, planes, yb - ya, store, true);
      }
    }
    hwy::FlushStream();  // the block's stream stores (write_row) before the caller reads them
  }, kTileRows / 4);
}

// filter_channels with the channel count as a compile-time constant (the sums stay in
// registers): n in [1, C].
template <int C, class Lobe, class Taps>
void filter_pass(const FilterConstants& k, const Channel* ch, int n, const cv::Rect& r, int nthreads,
                 const Lobe& lobe, Taps taps) {
  if constexpr (C > 1) {
    if (n < C) return filter_pass<C - 1>(k, ch, n, r, nthreads, lobe, taps);
  }
  filter_channels<C>(k, ch, r, nthreads, lobe, taps);
}

template <class Lobe, class Taps>
void filter_all(const FilterConstants& k, const std::vector<Channel>& channels, const cv::Rect& r,
                int nthreads, const Lobe& lobe, Taps taps) {
  const int n = int(channels.size());
  for (int first = 0; first < n; first += kMaxPassChannels)
    filter_pass<kMaxPassChannels>(k, channels.data() + first, std::min(kMaxPassChannels, n - first), r,
                                  nthreads, lobe, taps);
}

template <int C>
void box4(const cv::Mat& src, cv::Mat& dst, const cv::Rect& r, int nthreads) {
  using Pixel = cv::Vec<float, C>;
  const int width = src.cols, height = src.rows;
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const int ya = std::max(0, y - 2), yb = std::min(height - 1, y + 1);
      Pixel* out = dst.ptr<Pixel>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        const int xa = std::max(0, x - 2), xb = std::min(width - 1, x + 1);
        Pixel sum = Pixel::all(0.0f);
        for (int ty = ya; ty <= yb; ++ty) {
          const Pixel* in = src.ptr<Pixel>(ty);
          for (int tx = xa; tx <= xb; ++tx) sum += in[tx];
        }
        out[x] = sum * (1.0f / float((yb - ya + 1) * (xb - xa + 1)));
      }
    }
  });
}

void prepare_dst(const cv::Mat& src, cv::Mat& dst) {
  CV_Assert(src.type() == CV_32FC1 || src.type() == CV_32FC3);
  CV_Assert(dst.empty() || dst.data != src.data);
  if (dst.size() != src.size() || dst.type() != src.type()) dst.create(src.size(), src.type());
}

}  // namespace

// The filter of denoise_bilateral() (whose checks it assumes) for this instruction set.
void denoise_channels(std::span<const cv::Mat* const> srcs, const cv::Mat& depth_view, const cv::Mat& normal_view,
                      const cv::Mat& mask, const DenoiseSettings& settings, std::span<cv::Mat* const> dsts,
                      cv::Rect roi, int nthreads) {
  std::vector<Channel> channels;
  for (size_t i = 0; i < srcs.size(); ++i) {
    const cv::Mat& src = *srcs[i];
    prepare_dst(src, *dsts[i]);
    for (int c = 0; c < src.channels(); ++c) channels.push_back({srcs[i], dsts[i], c, src.channels()});
  }
  for (cv::Mat* dst : dsts)
    for (const cv::Mat* src : srcs) CV_Assert(dst->data != src->data);
  const cv::Rect r = resolve_roi(roi, depth_view.size());
  if (r.empty()) return;
  const FilterConstants k(depth_view, normal_view, mask, settings);
  if (settings.normal_power != float(DefaultLobe::kPower))
    filter_all(k, channels, r, nthreads, PowerLobe(settings.normal_power), k.taps);
  else if (k.taps == DefaultTaps::value)
    filter_all(k, channels, r, nthreads, DefaultLobe{}, DefaultTaps{});
  else
    filter_all(k, channels, r, nthreads, DefaultLobe{}, k.taps);
}

void box_blur_channels(const cv::Mat& src, cv::Mat& dst, cv::Rect roi, int nthreads) {
  prepare_dst(src, dst);
  const cv::Rect r = resolve_roi(roi, src.size());
  if (r.empty()) return;
  if (src.channels() == 1)
    box4<1>(src, dst, r, nthreads);
  else
    box4<3>(src, dst, r, nthreads);
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(denoise_channels);
HWY_EXPORT(box_blur_channels);
using HWY_NAMESPACE::kMaxRadiusPx;
constexpr int kMaxTapSpacingPx = 4;

std::string validate(const DenoiseSettings& s) {
  if (s.radius_px < 0 || s.radius_px > kMaxRadiusPx) return detail::out_of_range("radius_px", s.radius_px, "[0, 32]");
  if (s.tap_spacing_px < 1 || s.tap_spacing_px > kMaxTapSpacingPx)
    return detail::out_of_range("tap_spacing_px", s.tap_spacing_px, "[1, 4]");
  if (!(s.sigma_px > 0.0f) || !std::isfinite(s.sigma_px))
    return detail::out_of_range("sigma_px", s.sigma_px, "(0, inf)");
  if (!(s.depth_tolerance_relative > 0.0f) || !std::isfinite(s.depth_tolerance_relative))
    return detail::out_of_range("depth_tolerance_relative", s.depth_tolerance_relative, "(0, inf)");
  if (!(s.normal_power >= 0.0f && s.normal_power <= 256.0f))
    return detail::out_of_range("normal_power", s.normal_power, "[0, 256]");
  return {};
}

DenoiseSettings scaled_to_grid(const DenoiseSettings& s, int resolution_divisor) {
  CV_Assert(resolution_divisor >= 1);
  DenoiseSettings scaled = s;
  scaled.radius_px = std::min(kMaxRadiusPx, s.radius_px * resolution_divisor);
  scaled.sigma_px = s.sigma_px * float(resolution_divisor);
  scaled.tap_spacing_px = std::min(kMaxTapSpacingPx, s.tap_spacing_px * resolution_divisor);
  return scaled;
}

cv::Rect denoise_reads(const cv::Rect& roi, const DenoiseSettings& s, const cv::Size& size) {
  const int reach = s.radius_px / s.tap_spacing_px * s.tap_spacing_px;
  return cv::Rect(roi.x - reach, roi.y - reach, roi.width + 2 * reach, roi.height + 2 * reach) &
         cv::Rect(cv::Point(), size);
}

void denoise_bilateral(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
                       const cv::Mat& mask, const DenoiseSettings& settings, cv::Mat& dst,
                       cv::Rect roi, int nthreads) {
  const cv::Mat* srcs[] = {&src};
  cv::Mat* dsts[] = {&dst};
  denoise_bilateral(srcs, depth_view, normal_view, mask, settings, dsts, roi, nthreads);
}

void denoise_bilateral(std::span<const cv::Mat* const> srcs, const cv::Mat& depth_view,
                       const cv::Mat& normal_view, const cv::Mat& mask,
                       const DenoiseSettings& settings, std::span<cv::Mat* const> dsts,
                       cv::Rect roi, int nthreads) {
  CV_Assert(validate(settings).empty());
  CV_Assert(srcs.size() == dsts.size() && !srcs.empty());
  for (size_t i = 0; i < srcs.size(); ++i) {
    const cv::Mat& src = *srcs[i];
    CV_Assert(depth_view.type() == CV_32FC1 && depth_view.size() == src.size());
    CV_Assert(normal_view.type() == CV_32FC3 && normal_view.size() == src.size());
    CV_Assert(mask.type() == CV_8UC1 && mask.size() == src.size());
    for (size_t k = 0; k < i; ++k) CV_Assert(dsts[k] != dsts[i]);
  }
  HWY_DYNAMIC_DISPATCH(denoise_channels)(srcs, depth_view, normal_view, mask, settings, dsts, roi, nthreads);
}

void box_blur_4x4(const cv::Mat& src, cv::Mat& dst, cv::Rect roi, int nthreads) {
  HWY_DYNAMIC_DISPATCH(box_blur_channels)(src, dst, roi, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
