#include "kernels/half_resolution.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/half_resolution.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/cache_control.h>
#include <hwy/highway.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "core/half_samples.h"
#include "core/parallel.h"
#include "core/sample_planes.h"
#include "kernels/normals.h"
#include "kernels/positions.h"
#include "kernels/mask_lanes.h"
#include "kernels/position_lanes.h"
#include "kernels/thickness.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

namespace {

// Depth tolerance of the upsample, relative to the pixel's depth: a texel whose depth
// differs by 5% of the pixel's weighs exp(-1) of one at the same depth, so the texels of a
// surface behind a silhouette (depth gaps are tens of percent) carry ~nothing across it.
constexpr float kUpsampleDepthRelative = 0.05f;

// Below this total weight the four texels are exp(-9)-small: the pixel's surface is not
// among them (a thin feature or a silhouette); ratios would amplify noise.
constexpr float kMinUpsampleWeight = 1e-4f;

constexpr int kMaxChannels = 4;

// How far ahead of the pixels being blended their full-resolution guides are fetched into
// cache, in pixels (3 KiB of normals): the hardware's prefetch alone leaves the blend
// waiting on these rows' loads. 128 and 512 were slower than 256 on a Zen 4 core. (The half
// grid's build, which reads every other row, ran 5% slower with the same prefetch.)
constexpr int kPrefetchPx = 256;

// exp(x) of the weights' depth term, x <= 0: Cephes' expf (Moshier 1984-2000, "cephes
// math library", expf.c): n = floor(x log2(e) + 1/2), r = x - n ln 2 in two parts
// (Cody & Waite), e^r by its degree-7 minimax polynomial on [-ln 2 / 2, ln 2 / 2], times
// 2^n through the exponent bits; within 2 ulp of exp on the clamped range. The scalar
// and the vector form do the same operations in the same order (no fused multiply-add),
// so a weight has the same bits on every instruction set, whichever path computes it.
// x is clamped to -87 (exp = 1.6e-38, still a normal float): a weight that small never
// decides a blend (kMinUpsampleWeight). Near 0 (x > kExpTaylorFrom: the texel within 0.5% of
// the pixel's depth, as on most of a frame's smooth surfaces) exp is its degree-5 Taylor
// polynomial instead, 1 + x (1 + x (1/2 + x (1/6 + x (1/24 + x / 120)))): its truncation
// (|x|^6 / 720 < 1.4e-9) is far below a float's step there, and a vector of lanes all near
// 0 skips the range reduction.
constexpr float kExpMinArgument = -87.0f;
constexpr float kExpTaylorFrom = -0.1f;
constexpr float kExpTaylor[5] = {1.0f / 120.0f, 1.0f / 24.0f, 1.0f / 6.0f, 0.5f, 1.0f};
constexpr float kLog2e = 1.44269504088896341f;
constexpr float kLn2High = 0.693359375f, kLn2Low = -2.12194440e-4f;
constexpr float kExpPoly[6] = {1.9875691500e-4f, 1.3981999507e-3f, 8.3334519073e-3f,
                               4.1665795894e-2f, 1.6666665459e-1f, 5.0000001201e-1f};

inline float depth_falloff(float x) {
  if (x > kExpTaylorFrom) {
    float q = kExpTaylor[0];
    for (int i = 1; i < 5; ++i) q = q * x + kExpTaylor[i];
    return x * q + 1.0f;
  }
  x = std::max(x, kExpMinArgument);
  const float n = std::floor(x * kLog2e + 0.5f);
  const float r = (x - n * kLn2High) - n * kLn2Low;
  float p = kExpPoly[0];
  for (int i = 1; i < 6; ++i) p = p * r + kExpPoly[i];
  const float e = p * (r * r) + r + 1.0f;
  return e * std::bit_cast<float>(uint32_t(int32_t(n) + 127) << 23);
}

namespace hn = hwy::HWY_NAMESPACE;
using FloatLanes = hn::ScalableTag<float>;
using Lanes = hn::Vec<FloatLanes>;

// depth_falloff's Taylor polynomial (its form near 0) of every lane, by the same operations.
inline Lanes exp_taylor_lanes(Lanes x) {
  const FloatLanes d;
  Lanes q = hn::Set(d, kExpTaylor[0]);
  for (int i = 1; i < 5; ++i) q = hn::Add(hn::Mul(q, x), hn::Set(d, kExpTaylor[i]));
  return hn::Add(hn::Mul(x, q), hn::Set(d, 1.0f));
}

// depth_falloff of every lane, by the same operations; the range reduction only for a
// vector with a lane that needs it.
inline Lanes depth_falloff_lanes(Lanes x) {
  const FloatLanes d;
  const hn::RebindToSigned<FloatLanes> di;
  const auto near_zero = hn::Gt(x, hn::Set(d, kExpTaylorFrom));
  const Lanes taylor = exp_taylor_lanes(x);
  if (hn::AllTrue(d, near_zero)) return taylor;
  x = hn::Max(x, hn::Set(d, kExpMinArgument));
  const Lanes n = hn::Floor(hn::Add(hn::Mul(x, hn::Set(d, kLog2e)), hn::Set(d, 0.5f)));
  const Lanes r = hn::Sub(hn::Sub(x, hn::Mul(n, hn::Set(d, kLn2High))), hn::Mul(n, hn::Set(d, kLn2Low)));
  Lanes p = hn::Set(d, kExpPoly[0]);
  for (int i = 1; i < 6; ++i) p = hn::Add(hn::Mul(p, r), hn::Set(d, kExpPoly[i]));
  const Lanes e = hn::Add(hn::Add(hn::Mul(p, hn::Mul(r, r)), r), hn::Set(d, 1.0f));
  const auto bits = hn::ShiftLeft<23>(hn::Add(hn::ConvertTo(di, n), hn::Set(di, 127)));
  return hn::IfThenElse(near_zero, taylor, hn::Mul(e, hn::BitCast(d, bits)));
}

// depth_falloff_lanes of four vectors in place: where every lane of the four is near 0
// (most of a frame), their Taylor polynomials, one test for all four.
inline void depth_falloff_lanes(Lanes x[4]) {
  const FloatLanes d;
  const Lanes from = hn::Set(d, kExpTaylorFrom);
  const auto near_zero = hn::And(hn::And(hn::Gt(x[0], from), hn::Gt(x[1], from)),
                                 hn::And(hn::Gt(x[2], from), hn::Gt(x[3], from)));
  const bool taylor = hn::AllTrue(d, near_zero);
  for (int k = 0; k < 4; ++k) x[k] = taylor ? exp_taylor_lanes(x[k]) : depth_falloff_lanes(x[k]);
}

// A half-grid row's view-space positions, as view_positions_from_depth at each texel's
// source pixel (sx, sy) (source: the row's (sx, sy) pairs, sx < 0 where the texel has none,
// whose position is 0; depth: the sources' planar depths), a vector of texels at a time.
void positions_at_sources(const PixelDepthLanes& solve, const Camera& camera, const int32_t* source,
                          const float* depth, int n, float* out) {
  const FloatLanes d;
  const hn::RebindToSigned<FloatLanes> di;
  const int lanes = int(hn::Lanes(d));
  const Lanes centre = hn::Set(d, 0.5f);
  int i = 0;
  for (; i + lanes <= n; i += lanes) {
    hn::Vec<decltype(di)> sx, sy;
    hn::LoadInterleaved2(di, source + size_t(2) * size_t(i), sx, sy);
    Lanes x, y, z;
    solve(hn::Add(hn::ConvertTo(d, sx), centre), hn::Add(hn::ConvertTo(d, sy), centre), hn::LoadU(d, depth + i), x,
          y, z);
    const auto has_source = hn::RebindMask(d, hn::Gt(sx, hn::Set(di, -1)));
    hn::StoreInterleaved3(hn::IfThenElseZero(has_source, x), hn::IfThenElseZero(has_source, y),
                          hn::IfThenElseZero(has_source, z), d, out + size_t(3) * size_t(i));
  }
  for (; i < n; ++i) {
    const int32_t sx = source[2 * i], sy = source[2 * i + 1];
    store_position_or_zero(camera, sx >= 0, sx + 0.5f, sy + 0.5f, depth[i], out + size_t(3) * size_t(i));
  }
}

// Texels i .. i + N - 1 of half-grid row j whose blocks' first pixels (2i, 2j) .. are all
// foreground (most of a frame's): their sources are those pixels, and their depths,
// normals and positions the even lanes of the pixels' (ConcatEven). Returns false, having
// written nothing, where one is background.
bool half_grid_lanes(const FullGrid& full, HalfGrid& h, int j, int i, bool copy_position) {
#if HWY_TARGET == HWY_SCALAR  // one lane: no even lanes to concatenate
  (void)full, (void)h, (void)j, (void)i, (void)copy_position;
  return false;
#else
  const FloatLanes d;
  const hn::RebindToSigned<FloatLanes> di;
  const hn::Rebind<uint8_t, FloatLanes> d8;
  const int n = int(hn::Lanes(d)), x = 2 * i, y = 2 * j;
  hn::Vec<decltype(d8)> even_mask, odd_mask;
  hn::LoadInterleaved2(d8, full.mask.ptr<uint8_t>(y) + x, even_mask, odd_mask);
  if (!hn::AllFalse(d8, hn::Eq(even_mask, hn::Zero(d8)))) return false;
  Lanes even, odd;
  hn::LoadInterleaved2(d, full.depth_view.ptr<float>(y) + x, even, odd);
  hn::StoreU(even, d, h.depth_view.ptr<float>(j) + i);
  // The even pixels' 3-vectors of a row into texels i .. i + N - 1.
  const auto even_vectors = [&](const cv::Mat& from, cv::Mat& to) {
    const float* src = from.ptr<float>(y) + size_t(3) * size_t(x);
    Lanes a[3], b[3];
    hn::LoadInterleaved3(d, src, a[0], a[1], a[2]);
    hn::LoadInterleaved3(d, src + 3 * n, b[0], b[1], b[2]);
    hn::StoreInterleaved3(hn::ConcatEven(d, b[0], a[0]), hn::ConcatEven(d, b[1], a[1]), hn::ConcatEven(d, b[2], a[2]),
                          d, to.ptr<float>(j) + size_t(3) * size_t(i));
  };
  even_vectors(full.normal_view, h.normal_view);
  if (copy_position) even_vectors(full.position_view, h.position_view);
  hn::StoreU(hn::Set(d8, uint8_t(255)), d8, h.mask.ptr<uint8_t>(j) + i);
  const auto sx = hn::Add(hn::Set(di, x), hn::ShiftLeft<1>(hn::Iota(di, 0)));
  hn::StoreInterleaved2(sx, hn::Set(di, y), di, h.source.ptr<int32_t>(j) + size_t(2) * size_t(i));
  return true;
#endif
}

// Half-grid row j: each texel's source, the first foreground pixel of its 2x2 block (in
// row-major order), and the source's mask, depth and normal (and position, when
// copy_position: the frame has positions); texels without one are masked, at infinite
// depth, with zero vectors. A vector of texels at a time where their blocks' first pixels
// are foreground (half_grid_lanes), texel by texel elsewhere.
void half_grid_row(const FullGrid& full, HalfGrid& h, int j, bool copy_position) {
  const cv::Size size = full.depth_view.size();
  cv::Vec2i* source = h.source.ptr<cv::Vec2i>(j);
  uint8_t* mask = h.mask.ptr<uint8_t>(j);
  float* depth = h.depth_view.ptr<float>(j);
  cv::Vec3f* normal = h.normal_view.ptr<cv::Vec3f>(j);
  cv::Vec3f* position = copy_position ? h.position_view.ptr<cv::Vec3f>(j) : nullptr;
  // The block's two full-resolution mask rows (the second is the first's on a last odd row,
  // where it is not looked at).
  const int y0 = 2 * j, y1 = std::min(2 * j + 1, size.height - 1);
  const uint8_t* mask_rows[2] = {full.mask.ptr<uint8_t>(y0), full.mask.ptr<uint8_t>(y1)};
  const int n = int(hn::Lanes(FloatLanes()));
  for (int i = 0; i < h.source.cols;) {
    if (n > 1 && 2 * (i + n) <= size.width && half_grid_lanes(full, h, j, i, copy_position)) {
      i += n;
      continue;
    }
    const int end = std::min(i + n, h.source.cols);
    for (; i < end; ++i) {
      int sx = -1, sy = -1;
      for (int k = 0; k < 4 && sx < 0; ++k) {
        const int x = 2 * i + (k & 1), y = y0 + (k >> 1);
        if (x < size.width && y < size.height && mask_rows[k >> 1][x]) sx = x, sy = y;
      }
      source[i] = cv::Vec2i(sx, sy);
      mask[i] = sx < 0 ? 0 : 255;
      depth[i] = sx < 0 ? std::numeric_limits<float>::infinity() : full.depth_view.ptr<float>(sy)[sx];
      normal[i] = sx < 0 ? cv::Vec3f(0, 0, 0) : full.normal_view.ptr<cv::Vec3f>(sy)[sx];
      if (position) position[i] = sx < 0 ? cv::Vec3f(0, 0, 0) : full.position_view.ptr<cv::Vec3f>(sy)[sx];
    }
  }
}

void write_scalar(float* dst, const cv::Scalar& v, int channels) {
  for (int ch = 0; ch < channels; ++ch) dst[ch] = float(v[ch]);
}

}  // namespace

void build_half_grid(const FullGrid& full, HalfGrid& h, int nthreads, bool with_positions) {
  const cv::Size size = full.depth_view.size();
  const cv::Size half((size.width + 1) / 2, (size.height + 1) / 2);
  h.depth_view.create(half, CV_32FC1);
  h.normal_view.create(half, CV_32FC3);
  const bool has_position = with_positions;
  const bool positions_given = !full.position_view.empty();
  if (positions_given) CV_Assert(full.position_view.type() == CV_32FC3 && full.position_view.size() == size);
  if (has_position) h.position_view.create(half, CV_32FC3);
  else h.position_view.release();
  h.mask.create(half, CV_8UC1);
  h.source.create(half, CV_32SC2);
  h.camera = full.camera;
  h.camera.width_px = half.width;
  h.camera.height_px = half.height;
  const PixelDepthLanes solve(full.camera);
  parallel_rows(cv::Range(0, half.height), nthreads, [&](const cv::Range& rows) {
    for (int j = rows.start; j < rows.end; ++j) {
      half_grid_row(full, h, j, has_position && positions_given);
      if (has_position && !positions_given)
        positions_at_sources(solve, full.camera, h.source.ptr<int32_t>(j), h.depth_view.ptr<float>(j), half.width,
                             h.position_view.ptr<float>(j));
    }
  });
}

cv::Rect half_grid_roi(const cv::Rect& r, const cv::Size& size) {
  // Pixel x reads texels floor(x / 2 - 0.25) - 1 .. + 2.
  return cv::Rect(r.x / 2 - 2, r.y / 2 - 2, r.width / 2 + 5, r.height / 2 + 5) &
         cv::Rect(0, 0, (size.width + 1) / 2, (size.height + 1) / 2);
}

namespace {

// The texels a full-resolution pixel reads along one axis (bilinear at the texel centres,
// texel centre t = pixel 2 t + 0.5): t0 and t0 + 1, clamped to the grid's n texels, and
// the bilinear fraction towards the second.
struct AxisFootprint {
  int t[2];
  float frac;
  int t0;  // unclamped, for the fallback's 4x4 neighbourhood
};

inline AxisFootprint axis_footprint(int pixel, int n) {
  const float f = (float(pixel) + 0.5f) * 0.5f - 0.5f;
  AxisFootprint a;
  a.t0 = int(std::floor(f));
  a.frac = f - float(a.t0);
  a.t[0] = std::clamp(a.t0, 0, n - 1);
  a.t[1] = std::clamp(a.t0 + 1, 0, n - 1);
  return a;
}

// The 2x2 texels of pixel (x, y): columns x.t, rows y.t.
struct Footprint {
  AxisFootprint x, y;
};

// Joint bilateral weights of the four texels k = (k & 1, k >> 1) of a foreground pixel of
// depth d and normal n (header: bilinear x exp(-|dz| / (tol d)) x max(0, n . n_k)^4), 0 on
// masked texels.
inline void texel_weights(const HalfGrid& h, const Footprint& f, float d, const cv::Vec3f& n, float w[4]) {
  const float inv_tol = 1.0f / (kUpsampleDepthRelative * d);
  for (int k = 0; k < 4; ++k) {
    const int i = f.x.t[k & 1], j = f.y.t[k >> 1];
    w[k] = 0.0f;
    if (!h.mask.ptr<uint8_t>(j)[i]) continue;
    const float wb = ((k & 1) ? f.x.frac : 1.0f - f.x.frac) * ((k >> 1) ? f.y.frac : 1.0f - f.y.frac);
    const float dz = std::abs(h.depth_view.ptr<float>(j)[i] - d) * inv_tol;
    float c = std::max(0.0f, n.dot(h.normal_view.ptr<cv::Vec3f>(j)[i]));
    c *= c;
    w[k] = wb * depth_falloff(-dz) * c * c;
  }
}

// The foreground texel of the 4x4 neighbourhood closest in depth to d, or false.
inline bool nearest_in_depth(const HalfGrid& h, const Footprint& f, float d, int& bi, int& bj) {
  const int hw = h.depth_view.cols, hh = h.depth_view.rows;
  bi = -1, bj = -1;
  float best = std::numeric_limits<float>::infinity();
  for (int dj = -1; dj <= 2; ++dj)
    for (int di = -1; di <= 2; ++di) {
      const int i = f.x.t0 + di, j = f.y.t0 + dj;
      if (i < 0 || j < 0 || i >= hw || j >= hh || !h.mask.ptr<uint8_t>(j)[i]) continue;
      const float dz = std::abs(h.depth_view.ptr<float>(j)[i] - d);
      if (dz < best) best = dz, bi = i, bj = j;
    }
  return bi >= 0;
}

// out = sum_k w_k v_k x (1 / sum_k w_k) over the texels of nonzero weight, in k order
// (masked texels, weight 0, are skipped: their values may be anything). One division per
// pixel for all its channels (inv_wsum): in the vector code a division costs as much as a
// channel's whole blend.
template <int C>
inline void blend(const cv::Mat& half, const Footprint& f, const float w[4], float inv_wsum, float* out) {
  float acc[C] = {};
  for (int k = 0; k < 4; ++k) {
    if (w[k] == 0.0f) continue;
    const float* v = half.ptr<float>(f.y.t[k >> 1]) + size_t(f.x.t[k & 1]) * C;
    for (int ch = 0; ch < C; ++ch) acc[ch] += w[k] * v[ch];
  }
  for (int ch = 0; ch < C; ++ch) out[ch] = acc[ch] * inv_wsum;
}

inline void blend_any(const cv::Mat& half, const Footprint& f, const float w[4], float inv_wsum, float* out) {
  switch (half.channels()) {
    case 1: blend<1>(half, f, w, inv_wsum, out); break;
    case 2: blend<2>(half, f, w, inv_wsum, out); break;
    case 3: blend<3>(half, f, w, inv_wsum, out); break;
    default: blend<4>(half, f, w, inv_wsum, out); break;
  }
}
// The row the upsample writes of each image (`rows[i]` for images[i]): the image's own
// row, or for a half-float image a float row that the strip converts once the row is
// finished (OutputRows).
using RowPointers = std::span<float* const>;

// Foreground pixel x of depth d and texel weights w of every image: the normalised blend,
// or the texel closest in depth, or the fallback (header).
void upsample_pixel(const HalfGrid& h, std::span<const UpsampleImage> images, RowPointers rows, const Footprint& f,
                    float d, const float w[4], int x) {
  float wsum = 0.0f;
  for (int k = 0; k < 4; ++k) wsum += w[k];
  if (!(wsum > kMinUpsampleWeight)) {
    int bi, bj;
    if (!nearest_in_depth(h, f, d, bi, bj)) {  // no foreground texel near: nothing known
      for (size_t i = 0; i < images.size(); ++i) {
        const int cn = images[i].half.channels();
        write_scalar(rows[i] + size_t(x) * size_t(cn), images[i].fallback, cn);
      }
      return;
    }
    for (size_t i = 0; i < images.size(); ++i) {
      const int cn = images[i].half.channels();
      std::copy_n(images[i].half.ptr<float>(bj) + size_t(bi) * size_t(cn), cn, rows[i] + size_t(x) * size_t(cn));
    }
    return;
  }
  const float inv_wsum = 1.0f / wsum;
  for (size_t i = 0; i < images.size(); ++i)
    blend_any(images[i].half, f, w, inv_wsum, rows[i] + size_t(x) * size_t(images[i].half.channels()));
}

// Pixels [x0, x1) of row y of every image.
void upsample_span(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images, RowPointers rows,
                   int y, const AxisFootprint& fy, int x0, int x1) {
  const uint8_t* mask_row = full.mask.ptr<uint8_t>(y);
  Footprint f;
  f.y = fy;
  for (int x = x0; x < x1; ++x) {
    if (!mask_row[x]) {
      for (size_t i = 0; i < images.size(); ++i) {
        const int cn = images[i].half.channels();
        write_scalar(rows[i] + size_t(x) * size_t(cn), images[i].background, cn);
      }
      continue;
    }
    const float d = full.depth_view.ptr<float>(y)[x];
    f.x = axis_footprint(x, h.depth_view.cols);
    float w[4];
    texel_weights(h, f, d, full.normal_view.ptr<cv::Vec3f>(y)[x], w);
    upsample_pixel(h, images, rows, f, d, w, x);
  }
}

// Rows of the upsample's last, smallest blocks (parallel_row_blocks): a block lays out each
// texel row it reads once (TexelRows; pixel rows 2j + 1 and 2j + 2 read the same two texel
// rows) and takes its row buffers once, so its first row costs more than the others and
// the blocks are few and large.
constexpr int kBlockGranularity = 4;

// Lanes of pixels at a time (Highway's full vector of floats: 8 with AVX2, 16 with
// AVX-512, 4 with NEON): the same operations as the per-pixel code in the same order,
// lane by lane, so the same bits. Pixel x (odd) + l, l = 0 .. N - 1, reads texel columns
// m + l / 2 and m + l / 2 + 1, m = (x - 1) / 2, with the bilinear fraction 0.25 for even
// l and 0.75 for odd l (exact in float for widths below 2^22).
namespace lanes {

constexpr int kMaxWidth = 1 << 22;
// Floats past a texel row's last texel, so that a full vector loads from any column.
constexpr int kPadding = 64;
static_assert(HWY_MAX_BYTES / sizeof(float) <= kPadding);

// Texel rows of the half grid laid out for a vector of pixels at a time: per row, one
// array per quantity, the weights' guides first (the depth, the normal's x, y, z), then
// each image's channels. The guides, read for every pixel, are indexed by pixel column p
// and hold the first texel of p's footprint, column clamp(floor((p - 1) / 2))
// (axis_footprint), its second at p + 2: each texel stands twice (pixels 2t + 1 and 2t + 2
// start at texel t), and the texels of pixels x .. x + N - 1 are two plain loads from x and
// x + 2. The images' channels, as many as a frame has terms, are indexed by texel column +
// 1, the edge texels repeated at 0 and hw + 1 (axis_footprint's clamp), so that a row stays
// small in cache: their texels of pixels x .. x + N - 1 are lanes 0 .. N / 2 from m + 1
// (LanePattern). A strip fills each row it reads once. A masked texel is stored with depth 0,
// normal 0 and values 0: its weight max(0, n . 0)^4 is then +0 exactly, as texel_weights
// gives it, and it adds +0 to every blend, so the lanes need neither its mask nor a test of
// its weight (a foreground texel's values are finite; a sum of floats that is zero is +0).
class TexelRows {
 public:
  static constexpr int kDepth = 0, kNormalX = 1, kNormalY = 2, kNormalZ = 3, kGuides = 4;

  TexelRows(const HalfGrid& h, std::span<const UpsampleImage> images)
      : h_(h), images_(images), hw_(h.depth_view.cols), texel_length_(hw_ + 2 + kPadding) {
    int arrays = kGuides;
    for (const UpsampleImage& im : images) {
      image_first_.push_back(arrays);
      for (int ch = 0; ch < im.half.channels(); ++ch) background_.push_back(float(im.background[ch]));
      arrays += im.half.channels();
    }
    arrays_ = arrays;
    slot_length_ = size_t(kGuides) * size_t(guide_length()) + size_t(arrays_ - kGuides) * size_t(texel_length_);
    data_.assign(2 * slot_length_, 0.0f);
  }

  // Where array a starts in a row (from rows()): a guide's by pixel, an image channel's by
  // texel.
  size_t array_offset(int a) const {
    return a < kGuides ? size_t(a) * size_t(guide_length())
                       : size_t(kGuides) * size_t(guide_length()) + size_t(a - kGuides) * size_t(texel_length_);
  }
  int image_first(size_t i) const { return image_first_[i]; }
  // Channel ch of image i's background, as a float.
  float background(size_t i, int ch) const { return background_[size_t(image_first_[i] - kGuides + ch)]; }

  // Rows j0 and j1, filled unless the strip's previous pixel row read them.
  void rows(int j0, int j1, const float*& r0, const float*& r1) {
    int s0 = slot_of(j0);
    if (s0 < 0) fill(s0 = (slot_of(j1) == 0 ? 1 : 0), j0);
    int s1 = slot_of(j1);
    if (s1 < 0) fill(s1 = 1 - s0, j1);
    r0 = slot(s0);
    r1 = slot(s1);
  }

 private:
  int guide_length() const { return 2 * texel_length_; }
  int slot_of(int j) const { return row_[0] == j ? 0 : row_[1] == j ? 1 : -1; }
  float* slot(int s) { return data_.data() + size_t(s) * slot_length_; }

  // The `channels` channels of an interleaved texel row into the consecutive planes from
  // `planes` (texel_length_ apart), at column + 1 (sample_planes::split: a vector of texels
  // at a time).
  void split_texels(float* planes, const float* src, int channels) {
    float* plane[kMaxChannels];  // channels <= kMaxChannels (upsample_from_half_grid checks)
    for (int c = 0; c < channels; ++c) plane[c] = planes + size_t(c) * size_t(texel_length_) + 1;
    sample_planes::split(src, hw_, channels, plane);
  }

  // Texel row j into slot s: the guides (fill_guides), then the images' channels by texel
  // (column + 1), masked texels cleared, the edge texels repeated at 0 and hw + 1.
  void fill(int s, int j) {
    float* base = slot(s);
    const uint8_t* m = h_.mask.ptr<uint8_t>(j);
    fill_guides(base, j, m);
    for (size_t k = 0; k < images_.size(); ++k)
      split_texels(base + array_offset(image_first_[k]), images_[k].half.ptr<float>(j), images_[k].half.channels());
    const FloatLanes d;
    const int n = int(hn::Lanes(d));
    int i = 0;
    for (; i + n <= hw_; i += n) {
      const auto fg = foreground_lanes(m + i);
      if (hn::AllTrue(d, fg)) continue;
      for (int a = kGuides; a < arrays_; ++a) {
        float* t = base + array_offset(a) + 1 + i;
        hn::StoreU(hn::IfThenElseZero(fg, hn::LoadU(d, t)), d, t);
      }
    }
    for (; i < hw_; ++i)
      if (!m[i])
        for (int a = kGuides; a < arrays_; ++a) base[array_offset(a) + size_t(i) + 1] = 0.0f;
    for (int a = kGuides; a < arrays_; ++a) {
      float* t = base + array_offset(a);
      t[0] = t[1];
      t[hw_ + 1] = t[hw_];
    }
    row_[s] = j;
  }

  // The guides of texel row j (mask m) by pixel: texel t at pixels 2t + 1 and 2t + 2 (0
  // where masked), texel 0 again at pixel 0 and texel hw - 1 at 2 hw + 1 and 2 hw + 2 (the
  // edge repeats); a vector of texels at a time from the grid's rows, the row's tail one by
  // one.
  void fill_guides(float* base, int j, const uint8_t* m) {
    const float* depth = h_.depth_view.ptr<float>(j);
    const float* normal = h_.normal_view.ptr<float>(j);
    float* guide[kGuides];
    for (int a = 0; a < kGuides; ++a) guide[a] = base + array_offset(a);
    const FloatLanes d;
    const int n = int(hn::Lanes(d));
    int i = 0;
    for (; i + n <= hw_; i += n) {
      const auto fg = foreground_lanes(m + i);
      Lanes v[kGuides];
      v[kDepth] = hn::LoadU(d, depth + i);
      hn::LoadInterleaved3(d, normal + size_t(3) * size_t(i), v[kNormalX], v[kNormalY], v[kNormalZ]);
      for (int a = 0; a < kGuides; ++a) {
        const Lanes kept = hn::IfThenElseZero(fg, v[a]);
        hn::StoreInterleaved2(kept, kept, d, guide[a] + 1 + 2 * i);
      }
    }
    for (; i < hw_; ++i) {
      const float v[kGuides] = {depth[i], normal[3 * i], normal[3 * i + 1], normal[3 * i + 2]};
      for (int a = 0; a < kGuides; ++a) guide[a][1 + 2 * i] = guide[a][2 + 2 * i] = m[i] ? v[a] : 0.0f;
    }
    for (int a = 0; a < kGuides; ++a) {
      guide[a][0] = guide[a][1];
      guide[a][2 * hw_ + 1] = guide[a][2 * hw_ + 2] = guide[a][2 * hw_];
    }
  }

  const HalfGrid& h_;
  std::span<const UpsampleImage> images_;
  int hw_, texel_length_, arrays_ = 0;
  size_t slot_length_ = 0;
  std::vector<int> image_first_;
  std::vector<float> background_;
  std::vector<float> data_;
  int row_[2] = {-1, -1};
};

// Per lane l: which texel column of an image's loaded ones it reads (l / 2 for the first
// texel of its footprint, l / 2 + 1 for the second) and its horizontal bilinear weights.
using LaneIndices = decltype(hn::SetTableIndices(FloatLanes(), static_cast<const int32_t*>(nullptr)));
struct LanePattern {
  LaneIndices column[2];
  Lanes wx[2];

  LanePattern() {
    const FloatLanes d;
    const hn::RebindToSigned<FloatLanes> di;
    const auto half_lane = hn::ShiftRight<1>(hn::Iota(di, 0));
    column[0] = hn::IndicesFromVec(d, half_lane);
    column[1] = hn::IndicesFromVec(d, hn::Add(half_lane, hn::Set(di, 1)));
    const auto odd = hn::RebindMask(d, hn::Eq(hn::And(hn::Iota(di, 0), hn::Set(di, 1)), hn::Set(di, 1)));
    const Lanes frac_x = hn::IfThenElse(odd, hn::Set(d, 0.75f), hn::Set(d, 0.25f));
    wx[0] = hn::Sub(hn::Set(d, 1.0f), frac_x);
    wx[1] = frac_x;
  }
};

// The texels of pixels x .. x + N - 1 (x odd): the first of each pixel's footprint columns
// (k = 0) or the second (k = 1), from a guide (by pixel) or an image's channel (by texel).
inline Lanes guide_lanes(const float* guide, int x, int k) { return hn::LoadU(FloatLanes(), guide + x + 2 * k); }
inline Lanes image_lanes(const float* texels, int x, const LanePattern& p, int k) {
  return hn::TableLookupLanes(hn::LoadU(FloatLanes(), texels + (x - 1) / 2 + 1), p.column[k]);
}

// What the vector code of pixel row y reads: its two texel rows (from `texels`), their
// vertical bilinear weights and the row's full-resolution guides.
struct PixelRow {
  const float* r0;
  const float* r1;
  // Guide a of texel row r (TexelRows::kDepth .. kNormalZ), by pixel.
  const float* guide[2][TexelRows::kGuides];
  float wy[2];
  const float* depth;
  const float* normal;
  const uint8_t* mask;

  PixelRow(TexelRows& texels, const FullGrid& full, int y, const AxisFootprint& fy)
      : wy{1.0f - fy.frac, fy.frac},
        depth(full.depth_view.ptr<float>(y)),
        normal(full.normal_view.ptr<float>(y)),
        mask(full.mask.ptr<uint8_t>(y)) {
    texels.rows(fy.t[0], fy.t[1], r0, r1);
    for (int a = 0; a < TexelRows::kGuides; ++a)
      guide[0][a] = r0 + texels.array_offset(a), guide[1][a] = r1 + texels.array_offset(a);
  }

  // The array at `offset` (TexelRows::array_offset) of texel row k >> 1 of the footprint.
  const float* array(int k, size_t offset) const { return ((k >> 1) ? r1 : r0) + offset; }

  // The cache lines of the row's depth, normal and mask from pixel x on: a vector's share
  // (16 pixels at most, 64 bytes of depth, 192 of normals). A vector of fewer lanes asks for
  // 16 pixels' lines too, which the next vector asks for again: asking once per 16 pixels
  // instead ran slower on AVX2. No loop with a run-time count: GCC removes a loop whose only
  // effect is a prefetch.
  void prefetch_guides(int x) const {
    hwy::Prefetch(depth + x);
    for (int c = 0; c < 3; ++c) hwy::Prefetch(normal + size_t(3) * size_t(x) + size_t(16 * c));
    hwy::Prefetch(mask + x);
  }

  // texel_weights of pixels x .. x + N - 1 (x odd), 0 where `fg` is not (and, through
  // their zero normals, on masked texels: TexelRows).
  void weights(int x, const LanePattern& p, hn::Mask<FloatLanes> fg, Lanes w[4]) const {
    const FloatLanes d;
    const Lanes zero = hn::Zero(d);
    const Lanes depth_px = hn::LoadU(d, depth + x);
    Lanes nx, ny, nz;
    hn::LoadInterleaved3(d, normal + size_t(3) * size_t(x), nx, ny, nz);
    prefetch_guides(x + kPrefetchPx);
    const Lanes inv_tol = hn::Div(hn::Set(d, 1.0f), hn::Mul(hn::Set(d, kUpsampleDepthRelative), depth_px));
    // exp(-dz) of the four texels; exp(0) on background pixels, whose weight is 0 anyway
    // (set below).
    Lanes e[4];
    HWY_UNROLL(4)
    for (int k = 0; k < 4; ++k) {
      const Lanes texel_depth = guide_lanes(guide[k >> 1][TexelRows::kDepth], x, k & 1);
      e[k] = hn::IfThenElseZero(fg, hn::Neg(hn::Mul(hn::Abs(hn::Sub(texel_depth, depth_px)), inv_tol)));
    }
    depth_falloff_lanes(e);
    HWY_UNROLL(4)
    for (int k = 0; k < 4; ++k) {
      const int c = k & 1;
      const Lanes wb = hn::Mul(p.wx[c], hn::Set(d, wy[k >> 1]));
      Lanes cos = hn::Add(zero, hn::Mul(nx, guide_lanes(guide[k >> 1][TexelRows::kNormalX], x, c)));
      cos = hn::Add(cos, hn::Mul(ny, guide_lanes(guide[k >> 1][TexelRows::kNormalY], x, c)));
      cos = hn::Add(cos, hn::Mul(nz, guide_lanes(guide[k >> 1][TexelRows::kNormalZ], x, c)));
      cos = hn::Max(cos, zero);  // as std::max(0, c)
      cos = hn::Mul(cos, cos);
      w[k] = hn::IfThenElseZero(fg, hn::Mul(hn::Mul(hn::Mul(wb, e[k]), cos), cos));
    }
  }
};

}  // namespace lanes

// The pixels of row y in [x0, x1) that the vector code takes: from the first odd x, whole
// vectors (the others go pixel by pixel).
struct LaneSpan {
  int begin, end;
};

inline LaneSpan lane_span(int x0, int x1, int width) {
  const int n = int(hn::Lanes(FloatLanes()));
  if (n >= 2 && width < lanes::kMaxWidth) {  // a lane reads two texel columns
    const int begin = std::max(x0, 1) | 1;
    if (begin + n <= x1) return {begin, begin + (x1 - begin) / n * n};
  }
  return {x1, x1};
}

// std::clamp(v, 0, 1) of every lane, by its comparisons.
inline Lanes clamp_unit_lanes(Lanes v) {
  const FloatLanes d;
  const Lanes zero = hn::Zero(d), one = hn::Set(d, 1.0f);
  return hn::IfThenElse(hn::Lt(v, zero), zero, hn::IfThenElse(hn::Lt(one, v), one, v));
}

// The 3-vectors v of a vector of pixels normalised where `fg`: v / |v|, or the pixel's
// normal (n, interleaved) where |v| <= 1e-12, |v| = sqrt((x^2 + y^2) + z^2) in float (IEEE
// square root and products: the same bits in every lane width and as unit_vector).
inline void unit_vector_lanes(Lanes v[3], const float* n, hn::Mask<FloatLanes> fg) {
  const FloatLanes d;
  const Lanes len = hn::Sqrt(hn::Add(hn::Add(hn::Mul(v[0], v[0]), hn::Mul(v[1], v[1])), hn::Mul(v[2], v[2])));
  const auto long_enough = hn::Gt(len, hn::Set(d, 1e-12f));
  const auto unit = hn::And(fg, long_enough), normal = hn::AndNot(long_enough, fg);
  const Lanes inv = hn::Div(hn::Set(d, 1.0f), len);
  for (int c = 0; c < 3; ++c) v[c] = hn::IfThenElse(unit, hn::Mul(v[c], inv), v[c]);
  if (hn::AllFalse(d, normal)) return;  // a vanishing bent normal is rare
  Lanes nv[3];
  hn::LoadInterleaved3(d, n, nv[0], nv[1], nv[2]);
  for (int c = 0; c < 3; ++c) v[c] = hn::IfThenElse(normal, nv[c], v[c]);
}

// A foreground pixel's 3-vector p normalised (unit_vector_lanes), its normal n in place of
// a vanishing one.
inline void unit_vector(float* p, const float* n) {
  const float len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
  for (int c = 0; c < 3; ++c) p[c] = len > 1e-12f ? p[c] * (1.0f / len) : n[c];
}

// The images' finish (UpsampleFinish) on pixels [x0, x1) of row y, once they are
// upsampled pixel by pixel (the vector code finishes its lanes in registers: blend_image).
void finish_row(const FullGrid& full, std::span<const UpsampleImage> images, RowPointers rows, int y, int x0,
                int x1) {
  const uint8_t* mask_row = full.mask.ptr<uint8_t>(y);
  for (size_t i = 0; i < images.size(); ++i) {
    float* row = rows[i];
    if (images[i].finish == UpsampleFinish::clamp_unit_interval) {
      for (int x = x0; x < x1; ++x) row[x] = std::clamp(row[x], 0.0f, 1.0f);
    } else if (images[i].finish == UpsampleFinish::unit_vector) {
      const float* normal_row = full.normal_view.ptr<float>(y);
      for (int x = x0; x < x1; ++x)
        if (mask_row[x]) unit_vector(row + size_t(3) * size_t(x), normal_row + size_t(3) * size_t(x));
    }
  }
}

// Image i's values (C channels) of pixels x .. x + N - 1 of a row (x odd, the row's texels
// in `row`), from weights w and the inverse of their sum: the blend where a pixel is
// foreground, the background elsewhere, stored interleaved at `out`. C at compile time, so
// that a channel's texel offsets and sums stay in registers.
template <int C>
void blend_image(const lanes::TexelRows& texels, const lanes::PixelRow& row, const lanes::LanePattern& p, size_t i,
                 UpsampleFinish finish, const Lanes w[4], Lanes inv_wsum, hn::Mask<FloatLanes> fg, int x, float* out) {
  const FloatLanes d;
  const Lanes zero = hn::Zero(d);
  Lanes value[C];
  for (int ch = 0; ch < C; ++ch) {
    const size_t offset = texels.array_offset(texels.image_first(i) + ch);
    Lanes acc = zero;
    for (int k = 0; k < 4; ++k) {
      const Lanes v = lanes::image_lanes(row.array(k, offset), x, p, k & 1);
      acc = hn::Add(acc, hn::Mul(w[k], v));  // + 0 where blend skips the texel (TexelRows)
    }
    value[ch] = hn::IfThenElse(fg, hn::Mul(acc, inv_wsum), hn::Set(d, texels.background(i, ch)));
  }
  if constexpr (C == 1)
    if (finish == UpsampleFinish::clamp_unit_interval) value[0] = clamp_unit_lanes(value[0]);
  if constexpr (C == 3)
    if (finish == UpsampleFinish::unit_vector) unit_vector_lanes(value, row.normal + size_t(3) * size_t(x), fg);
  if constexpr (C == 1) hn::StoreU(value[0], d, out);
  if constexpr (C == 2) hn::StoreInterleaved2(value[0], value[1], d, out);
  if constexpr (C == 3) hn::StoreInterleaved3(value[0], value[1], value[2], d, out);
  if constexpr (C == 4) hn::StoreInterleaved4(value[0], value[1], value[2], value[3], d, out);
}

// The images' values of pixels x .. x + N - 1 of a row (blend_image) from weights w and
// their sum (pixels whose weights are too small are redone one by one after). An image has
// 1 to kMaxChannels channels (upsample_from_half_grid checks).
static_assert(kMaxChannels == 4, "blend_lanes has a case per channel count");
void blend_lanes(const lanes::TexelRows& texels, const lanes::PixelRow& row, const lanes::LanePattern& p,
                 std::span<const UpsampleImage> images, RowPointers rows, const Lanes w[4], Lanes wsum,
                 hn::Mask<FloatLanes> fg, int x) {
  const Lanes inv_wsum = hn::Div(hn::Set(FloatLanes(), 1.0f), wsum);
  for (size_t i = 0; i < images.size(); ++i) {
    const int cn = images[i].half.channels();
    float* out = rows[i] + size_t(x) * size_t(cn);
    switch (cn) {
      case 1: blend_image<1>(texels, row, p, i, images[i].finish, w, inv_wsum, fg, x, out); break;
      case 2: blend_image<2>(texels, row, p, i, images[i].finish, w, inv_wsum, fg, x, out); break;
      case 3: blend_image<3>(texels, row, p, i, images[i].finish, w, inv_wsum, fg, x, out); break;
      default: blend_image<4>(texels, row, p, i, images[i].finish, w, inv_wsum, fg, x, out); break;
    }
  }
}

// Pixels [span.begin, span.end) of row y, a vector at a time.
void upsample_lanes(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images,
                    RowPointers rows, lanes::TexelRows& texels, const lanes::LanePattern& p, const AxisFootprint& fy,
                    const LaneSpan& span, int y) {
  const FloatLanes d;
  const size_t n = hn::Lanes(d);
  const lanes::PixelRow row(texels, full, y, fy);
  for (int x = span.begin; x < span.end; x += int(n)) {
    const auto fg = foreground_lanes(row.mask + x);
    Lanes w[4];
    row.weights(x, p, fg, w);
    Lanes wsum = hn::Zero(d);
    for (int k = 0; k < 4; ++k) wsum = hn::Add(wsum, w[k]);
    blend_lanes(texels, row, p, images, rows, w, wsum, fg, x);
    // Foreground pixels whose weights are too small go pixel by pixel.
    const auto low = hn::AndNot(hn::Gt(wsum, hn::Set(d, kMinUpsampleWeight)), fg);
    if (hn::AllFalse(d, low)) continue;
    HWY_ALIGN float wl[4][lanes::kPadding], low_lane[lanes::kPadding];
    for (int k = 0; k < 4; ++k) hn::Store(w[k], d, wl[k]);
    hn::Store(hn::VecFromMask(d, low), d, low_lane);
    Footprint f;
    f.y = fy;
    for (size_t l = 0; l < n; ++l) {
      if (std::bit_cast<uint32_t>(low_lane[l]) == 0) continue;
      const int xl = x + int(l);
      f.x = axis_footprint(xl, h.depth_view.cols);
      const float wp[4] = {wl[0][l], wl[1][l], wl[2][l], wl[3][l]};
      upsample_pixel(h, images, rows, f, row.depth[xl], wp, xl);
      finish_row(full, images, rows, y, xl, xl + 1);
    }
  }
}

// The rows the upsample writes for a strip of rows (RowPointers): a float image's own rows;
// a half-float image's values go to a float row first and are stored in half once the row
// is finished (half_samples::to_half: round to nearest even, OpenEXR's bits).
class OutputRows {
 public:
  OutputRows(std::span<const UpsampleImage> images, int width) : images_(images), rows_(images.size()) {
    scratch_.resize(images.size());
    for (size_t i = 0; i < images.size(); ++i)
      if (images[i].full.depth() == CV_16F) scratch_[i].resize(size_t(width) * size_t(images[i].half.channels()));
  }

  // The rows of pixel row y.
  RowPointers at(int y) {
    for (size_t i = 0; i < images_.size(); ++i)
      rows_[i] = scratch_[i].empty() ? images_[i].full.ptr<float>(y) : scratch_[i].data();
    return rows_;
  }

  // Pixels [x0, x1) of row y, finished: stored in the half-float images.
  void store(int y, int x0, int x1) const {
    for (size_t i = 0; i < images_.size(); ++i) {
      if (scratch_[i].empty()) continue;
      const size_t cn = size_t(images_[i].half.channels());
      half_samples::to_half(scratch_[i].data() + size_t(x0) * cn, int(size_t(x1 - x0) * cn),
                            images_[i].full.ptr<uint16_t>(y) + size_t(x0) * cn);
    }
  }

 private:
  std::span<const UpsampleImage> images_;
  std::vector<float*> rows_;
  std::vector<std::vector<float>> scratch_;
};

}  // namespace

void sample_at_texels(const HalfGrid& h, const cv::Mat& full_image, cv::Mat& half_image, int nthreads) {
  CV_Assert(full_image.depth() == CV_32F);
  CV_Assert((full_image.cols + 1) / 2 == h.source.cols && (full_image.rows + 1) / 2 == h.source.rows);
  const int cn = full_image.channels();
  half_image.create(h.source.size(), full_image.type());
  parallel_rows(cv::Range(0, h.source.rows), nthreads, [&](const cv::Range& rows) {
    for (int j = rows.start; j < rows.end; ++j) {
      const cv::Vec2i* src = h.source.ptr<cv::Vec2i>(j);
      float* d = half_image.ptr<float>(j);
      for (int i = 0; i < h.source.cols; ++i, d += cn) {
        if (src[i][0] < 0) std::fill(d, d + cn, 0.0f);
        else std::copy_n(full_image.ptr<float>(src[i][1]) + size_t(src[i][0]) * size_t(cn), cn, d);
      }
    }
  });
}

void upsample_from_half_grid(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images,
                             const cv::Rect& r, int nthreads) {
  const int hh = h.depth_view.rows;
  for (const UpsampleImage& im : images) {
    CV_Assert(im.half.depth() == CV_32F && im.half.size() == h.depth_view.size());
    CV_Assert((im.full.depth() == CV_32F || im.full.depth() == CV_16F) && im.full.channels() == im.half.channels() &&
              im.full.size() == full.depth_view.size());
    CV_Assert(im.half.channels() <= kMaxChannels);
    CV_Assert(im.finish != UpsampleFinish::clamp_unit_interval || im.half.channels() == 1);
    CV_Assert(im.finish != UpsampleFinish::unit_vector || im.half.channels() == 3);
  }
  const LaneSpan span = lane_span(r.x, r.x + r.width, full.depth_view.cols);
  parallel_row_blocks(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    lanes::TexelRows texels(h, images);
    const std::optional<lanes::LanePattern> pattern =
        span.begin < span.end ? std::optional<lanes::LanePattern>(std::in_place) : std::nullopt;
    OutputRows outputs(images, full.depth_view.cols);
    for (int y = rows.start; y < rows.end; ++y) {
      const AxisFootprint fy = axis_footprint(y, hh);
      const RowPointers out = outputs.at(y);
      upsample_span(full, h, images, out, y, fy, r.x, span.begin);
      if (pattern) upsample_lanes(full, h, images, out, texels, *pattern, fy, span, y);
      upsample_span(full, h, images, out, y, fy, span.end, r.x + r.width);
      // The vector code finished its pixels in registers; the row's ends are finished here.
      finish_row(full, images, out, y, r.x, span.begin);
      finish_row(full, images, out, y, span.end, r.x + r.width);
      outputs.store(y, r.x, r.x + r.width);
    }
  }, kBlockGranularity);
}

float upsample_depth_falloff(float x) { return depth_falloff(x); }

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(build_half_grid);
HWY_EXPORT(sample_at_texels);
HWY_EXPORT(upsample_from_half_grid);

void build_half_grid(const FullGrid& full, HalfGrid& h, int nthreads, bool with_positions) {
  HWY_DYNAMIC_DISPATCH(build_half_grid)(full, h, nthreads, with_positions);
}

void sample_at_texels(const HalfGrid& h, const cv::Mat& full_image, cv::Mat& half_image, int nthreads) {
  HWY_DYNAMIC_DISPATCH(sample_at_texels)(h, full_image, half_image, nthreads);
}

void upsample_from_half_grid(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images,
                             const cv::Rect& r, int nthreads) {
  HWY_DYNAMIC_DISPATCH(upsample_from_half_grid)(full, h, images, r, nthreads);
}

// The weights' depth term is the same function on every target.
float upsample_depth_falloff(float x) { return HWY_NAMESPACE::upsample_depth_falloff(x); }

cv::Rect half_grid_roi(const cv::Rect& r, const cv::Size& size) { return HWY_NAMESPACE::half_grid_roi(r, size); }

LightReads light_reads(bool ao_multibounce, bool ssdo, bool frame_has_lighting) {
  return {ao_multibounce || (ssdo && !frame_has_lighting), ssdo && frame_has_lighting};
}

namespace {

// Which of the selected terms run on the half grid.
struct HalfTerms {
  bool ao, ssdo, confidence;
  bool any() const { return ao || ssdo || confidence; }
};

HalfTerms half_terms(const TermSettings& s) {
  return {s.ao != nullptr && runs_on_half_grid(*s.ao), s.ssdo != nullptr && runs_on_half_grid(*s.ssdo),
          s.confidence != nullptr && runs_on_half_grid(*s.confidence)};
}

void allocate(cv::Mat& image, const cv::Size& size, int type) {
  if (image.size() != size || image.type() != type) image.create(size, type);
}

// The full-resolution images of the half grid's AO and SSDO terms that the upsample writes,
// for those present (ao, ssdo): the raw ones (`raw`; in half with in_half.ao and
// in_half.ssdo) and the denoised ones (`denoised`).
void allocate_grid_terms(bool ao, bool ssdo, bool raw, bool denoised, const HalfOutputs& in_half,
                         const cv::Size& size, TermOutputs& out) {
  const int light = in_half.ssdo ? CV_16FC3 : CV_32FC3;
  if (ao && raw) allocate(out.ao.ao, size, in_half.ao ? CV_16FC1 : CV_32FC1);
  if (ao && denoised) allocate(out.denoised.ao, size, CV_32FC1);
  if (ssdo && raw) allocate(out.ssdo.direct, size, light), allocate(out.ssdo.indirect, size, light);
  if (ssdo && denoised)
    allocate(out.denoised.direct, size, CV_32FC3), allocate(out.denoised.indirect, size, CV_32FC3);
}

// The full-resolution images the upsample writes, as the kernels allocate their outputs.
void allocate_upsampled(const TermSettings& settings, const HalfTerms& half, const cv::Size& size,
                        TermOutputs& out) {
  allocate_grid_terms(half.ao, half.ssdo, /*raw=*/!settings.keep_grid_terms, settings.denoise != nullptr,
                      settings.stored_in_half, size, out);
  if (half.ao && has_bent_normal(*settings.ao))
    allocate(out.ao.bent_normal_view, size, settings.stored_in_half.bent_normal ? CV_16FC3 : CV_32FC3);
  else if (half.ao)
    out.ao.bent_normal_view.release();
  if (half.confidence) allocate(out.confidence, size, settings.stored_in_half.confidence ? CV_16FC1 : CV_32FC1);
}

// The second depth layer on a grid (depth, mask, camera of the grid; `file_back` the
// frame's own layer on that grid, or empty): the occupancy of all views when there are
// views, else the file's layer. Empty when none: AO then estimates its own from the grid's
// silhouettes when its settings ask for it (compute_ao), while SSDO keeps its constant
// thickness: its terms did not gain from the estimate (docs/accuracy.md, "Thickness from
// silhouettes"). With views and AO on this grid (ao_here) estimating, the occupancy starts
// from the estimate and is narrowed to it: the views only carve free space out of it. Their
// occupancy takes the other views' surfaces to be the constant thickness deep, which would
// thicken again what the silhouettes made thin (on the orbit shot it raised gtao high's
// error with views by a quarter), and started from the constant it leaves walls thin
// (medium's error with views doubled). SSDO then reads that layer too.
cv::Mat grid_back_layer(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                        const cv::Mat& file_back, const TermInputs& in, const TermSettings& settings,
                        bool ao_here, std::vector<ViewUse>& uses, int nthreads) {
  if (in.views.empty()) return file_back;
  cv::Mat own = file_back;
  const bool estimated = own.empty() && ao_here && estimates_back_layer(*settings.ao);
  if (estimated) estimate_back_depth(depth_view, mask, camera, settings.ao->silhouettes, own, nthreads);
  cv::Mat back;
  const MultiViewInputs grid{depth_view, mask, camera, own.empty() ? nullptr : &own};
  uses = occupancy_from_views(grid, in.views, multiview_settings(settings), back, nthreads);
  if (back.empty()) return own;
  if (estimated) cv::min(back, own, back);
  return back;
}

// The views the confidence counts as observers (a grid's depth, mask and camera): those the
// occupancy pass used, measured here when no AO or SSDO ran it. Empty without views.
std::vector<DepthView> confidence_observers(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                                            const TermInputs& in, const TermSettings& settings,
                                            std::vector<ViewUse>& uses, int nthreads) {
  if (in.views.empty()) return {};
  if (uses.size() != in.views.size())
    uses = measure_view_use({depth_view, mask, camera}, in.views, multiview_settings(settings), nthreads);
  std::vector<DepthView> used;
  for (size_t i = 0; i < uses.size(); ++i)
    if (uses[i].used) used.push_back(in.views[i]);
  return used;
}

// The second depth layer at the texels of the half grid (see grid_back_layer).
cv::Mat half_grid_back_layer(const HalfGrid& h, const TermInputs& in, const TermSettings& settings, bool ao_here,
                             std::vector<ViewUse>& uses, int nthreads) {
  cv::Mat file_back;
  if (in.depth_back_view != nullptr && !in.depth_back_view->empty())
    sample_at_texels(h, *in.depth_back_view, file_back, nthreads);
  return grid_back_layer(h.depth_view, h.mask, h.camera, file_back, in, settings, ao_here, uses, nthreads);
}

// One grid's inputs to AO and SSDO: the half grid's texels or the full-resolution images,
// extended by a guard band of off-screen texels when the views saw past the edges (the
// frame's grid is then `inside` these images).
struct GridInputs {
  cv::Mat depth_view, normal_view, position_view, mask;
  Camera camera;
  cv::Mat albedo, lighting, back;  // empty when the kernels do not read them
  cv::Rect inside;  // the frame's grid in these images; empty: the images are the grid
  cv::Point data_origin;  // TermInputs::data_origin_px in this grid's pixels
  cv::Point origin() const { return inside.tl(); }
  // The kernels' frame_origin_px: where the picture's pixel (0, 0) lies in these images.
  cv::Point picture_origin() const { return origin() - data_origin; }
};

// A point of the full grid's pixel space in the half grid's (floor(p / 2): texel i covers
// pixels 2i and 2i + 1, at any sign).
cv::Point on_half_grid(cv::Point p) { return {p.x >> 1, p.y >> 1}; }

// light_reads of the inputs and settings (the albedo only where the frame has one).
LightReads light_reads(const TermInputs& in, const TermSettings& s) {
  const bool lit = in.lighting != nullptr && !in.lighting->empty();
  LightReads r = ssdo::light_reads(s.ao && s.ao->multibounce, s.ssdo != nullptr, lit);
  r.albedo = r.albedo && in.albedo != nullptr && !in.albedo->empty();
  return r;
}
bool reads_albedo(const TermInputs& in, const TermSettings& s) { return light_reads(in, s).albedo; }
bool reads_lighting(const TermInputs& in, const TermSettings& s) { return light_reads(in, s).lighting; }

GridInputs half_grid_inputs(const HalfGrid& h, const TermInputs& in, const TermSettings& s, const cv::Mat& back,
                            int nthreads) {
  GridInputs g{h.depth_view, h.normal_view, h.position_view, h.mask, h.camera, {}, {}, back, {},
               on_half_grid(in.data_origin_px)};
  if (reads_albedo(in, s)) sample_at_texels(h, *in.albedo, g.albedo, nthreads);
  if (reads_lighting(in, s)) sample_at_texels(h, *in.lighting, g.lighting, nthreads);
  return g;
}

GridInputs full_grid_inputs(const TermInputs& in, const TermSettings& s, const cv::Mat& position_view,
                            const cv::Mat& back) {
  GridInputs g{in.depth_view, in.normal_view, position_view, in.mask, in.camera, {}, {}, back, {},
               in.data_origin_px};
  if (reads_albedo(in, s)) g.albedo = *in.albedo;
  if (reads_lighting(in, s)) g.lighting = *in.lighting;
  return g;
}

// The grid extended by the guard band (kernels/multiview.h) when some view is used and taps
// leave the picture. Band texels get positions and normals reconstructed from the views'
// depth, and the albedo and lighting of the view pixel they show where the views have them
// (else 0: a sender no view has light for stays dark).
void extend_grid_with_views(GridInputs& g, const TermInputs& in, const TermSettings& s,
                            std::span<const ViewUse> uses, int nthreads) {
  if (g.back.empty() || std::none_of(uses.begin(), uses.end(), [](const ViewUse& u) { return u.used; })) return;
  const float radius = s.ao ? s.ao->radius_world : s.ssdo->radius_world;
  const float max_radius_px = std::max(s.ao ? s.ao->max_radius_px : 0.0f, s.ssdo ? s.ssdo->max_radius_px : 0.0f);
  const int reach_px = guard_band_texels(g.depth_view, g.mask, g.camera, radius, max_radius_px, nthreads);
  if (reach_px == 0) return;
  GuardBand band;
  extend_with_views({g.depth_view, g.mask, g.camera}, g.back, in.views, uses, multiview_settings(s), reach_px, band,
                    nthreads);
  const BandMargins m = band.margins;
  if (!m.any()) return;
  const cv::Rect inside = band.inside();
  const auto pad = [&m](cv::Mat& image) {
    if (!image.empty()) cv::copyMakeBorder(image, image, m.top, m.bottom, m.left, m.right, cv::BORDER_CONSTANT, 0);
  };
  pad(g.normal_view);
  pad(g.position_view);
  pad(g.albedo);
  pad(g.lighting);
  const int w = band.camera.width_px, h = band.camera.height_px;
  for (const cv::Rect& side :
       {cv::Rect(0, 0, w, m.top), cv::Rect(0, h - m.bottom, w, m.bottom), cv::Rect(0, m.top, m.left, inside.height),
        cv::Rect(w - m.right, m.top, m.right, inside.height)}) {
    if (side.empty()) continue;  // an empty roi would mean the whole image
    reconstruct_normals_from_depth(band.depth_view, band.mask, band.camera, g.normal_view, side, nthreads);
    if (!g.position_view.empty())
      view_positions_from_depth(band.depth_view, band.mask, band.camera, g.position_view, side, nthreads);
    if (!g.albedo.empty() && !band.albedo.empty()) band.albedo(side).copyTo(g.albedo(side));
    if (!g.lighting.empty() && !band.lighting.empty()) band.lighting(side).copyTo(g.lighting(side));
  }
  g.depth_view = band.depth_view;
  g.mask = band.mask;
  g.back = band.depth_back_view;
  g.camera = band.camera;
  g.inside = inside;
}

// `roi` of the grid's own images from the extended images (only roi is written, as the
// kernels write; `out` allocated at the grid's size when needed).
void crop_from_band(const cv::Mat& extended, const GridInputs& g, const cv::Rect& roi, cv::Mat& out) {
  if (extended.empty()) {
    out.release();
    return;
  }
  const cv::Size size = g.inside.size();
  if (out.size() != size || out.type() != extended.type()) out.create(size, extended.type());
  extended(roi + g.origin()).copyTo(out(roi));
}

// AO on the grid's pixels of roi.
void ao_on_grid(const GridInputs& g, const AoSettings& s, const cv::Rect& roi, AoOutput& out, int nthreads) {
  const AoInputs grid{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera,
                      g.albedo.empty() ? nullptr : &g.albedo, g.back.empty() ? nullptr : &g.back, g.picture_origin()};
  if (g.inside.empty()) return compute_ao(grid, s, out, roi, nthreads);
  AoOutput extended;
  compute_ao(grid, s, extended, roi + g.origin(), nthreads);
  crop_from_band(extended.ao, g, roi, out.ao);
  crop_from_band(extended.bent_normal_view, g, roi, out.bent_normal_view);
}

// SSDO on the grid's pixels of roi. Albedo only scales the senders' direct light when the
// frame has no lighting.
void ssdo_on_grid(const GridInputs& g, const TermInputs& in, const SsdoSettings& s, const cv::Rect& roi,
                  SsdoOutput& out, int nthreads) {
  const bool lit = !g.lighting.empty();
  const SsdoInputs grid{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, *in.environment,
                        g.albedo.empty() || lit ? nullptr : &g.albedo, lit ? &g.lighting : nullptr,
                        g.back.empty() ? nullptr : &g.back, g.picture_origin()};
  if (g.inside.empty()) return compute_ssdo(grid, s, out, roi, nthreads);
  SsdoOutput extended;
  compute_ssdo(grid, s, extended, roi + g.origin(), nthreads);
  crop_from_band(extended.direct, g, roi, out.direct);
  crop_from_band(extended.indirect, g, roi, out.indirect);
}

// The upsample of the grid's raw AO and SSDO terms (those not empty in `raw`) into out's
// (allocated by the caller), added to `images`: AO clamped to [0, 1], 1 on background, SSDO
// 0 there.
void add_raw_grid_terms(const HalfGridTerms& raw, TermOutputs& out, std::vector<UpsampleImage>& images) {
  if (!raw.ao.empty())
    images.push_back({raw.ao, out.ao.ao, cv::Scalar(1.0), cv::Scalar(1.0), UpsampleFinish::clamp_unit_interval});
  if (!raw.direct.empty()) {
    images.push_back({raw.direct, out.ssdo.direct, cv::Scalar::all(0), cv::Scalar::all(0)});
    images.push_back({raw.indirect, out.ssdo.indirect, cv::Scalar::all(0), cv::Scalar::all(0)});
  }
}

// The grid's AO and SSDO terms (those not empty in `terms`) blurred on the grid with its
// guides over half_roi into grid_denoised (whose images the upsample then reads), and the
// upsample of each into `out` (allocated by the caller) added to `images`.
void denoise_grid_terms(const HalfGridTerms& terms, const DenoiseSettings& settings, const cv::Rect& half_roi,
                        DenoisedTerms& grid_denoised, DenoisedTerms& out, std::vector<UpsampleImage>& images,
                        int nthreads) {
  const HalfGrid& h = terms.grid;
  std::vector<const cv::Mat*> noisy;
  std::vector<cv::Mat*> denoised;
  if (!terms.ao.empty()) {
    noisy.push_back(&terms.ao), denoised.push_back(&grid_denoised.ao);
    images.push_back({grid_denoised.ao, out.ao, cv::Scalar(1.0), cv::Scalar(1.0), UpsampleFinish::clamp_unit_interval});
  }
  if (!terms.direct.empty()) {
    noisy.push_back(&terms.direct), denoised.push_back(&grid_denoised.direct);
    noisy.push_back(&terms.indirect), denoised.push_back(&grid_denoised.indirect);
    images.push_back({grid_denoised.direct, out.direct, cv::Scalar::all(0), cv::Scalar::all(0)});
    images.push_back({grid_denoised.indirect, out.indirect, cv::Scalar::all(0), cv::Scalar::all(0)});
  }
  // AO, then SSDO direct and indirect, in one pass: the weights are the grid's.
  if (!noisy.empty())
    denoise_bilateral(noisy, h.depth_view, h.normal_view, h.mask, settings, denoised, half_roi, nthreads);
}

// The settings of the kernels on the half grid: the pixel bounds of the picture
// (max_radius_px) in the grid's texels (max_radius_on_grid), so that a method reaches as far
// on either grid. Holds what its terms point to: not copied.
struct HalfGridSettings {
  AoSettings ao;
  SsdoSettings ssdo;
  ConfidenceSettings confidence;
  TermSettings terms;

  explicit HalfGridSettings(const TermSettings& s) : terms(s) {
    if (s.ao) ao = *s.ao, ao.max_radius_px = max_radius_on_grid(ao.max_radius_px, 2), terms.ao = &ao;
    if (s.ssdo) ssdo = *s.ssdo, ssdo.max_radius_px = max_radius_on_grid(ssdo.max_radius_px, 2), terms.ssdo = &ssdo;
    if (s.confidence) {
      confidence = *s.confidence;
      confidence.max_radius_px = max_radius_on_grid(confidence.max_radius_px, 2);
      terms.confidence = &confidence;
    }
  }
  HalfGridSettings(const HalfGridSettings&) = delete;
  HalfGridSettings& operator=(const HalfGridSettings&) = delete;
};

// The terms that run on the half grid: the grid (with positions when AO or SSDO runs on
// it), each kernel on the texels the upsample of r reads (and, with the denoise, the texels
// its taps read around them), the denoise of AO and SSDO on the grid, then one upsample of
// all their images. Background and no foreground texel near: AO 1 (unoccluded), bent
// normal 0 (set to the normal by its unit_vector finish), SSDO 0 (nothing known of the
// light), confidence 1. AO is clamped and the bent normals renormalised in the upsample's
// pass. With keep_grid_terms, the raw AO and SSDO terms stay on the grid (out.grid).
void compute_on_half_grid(const FullGrid& full, const TermInputs& in, const TermSettings& picture_settings,
                          const HalfTerms& half, TermOutputs& out, const cv::Rect& r, int nthreads,
                          const std::function<void()>& inputs_read) {
  const HalfGridSettings on_grid(picture_settings);
  const TermSettings& settings = on_grid.terms;
  // finish_half_grid_terms upsamples the whole frame from the kept terms.
  CV_Assert(!settings.keep_grid_terms || r == cv::Rect(cv::Point(), full.depth_view.size()));
  HalfGrid h;
  build_half_grid(full, h, nthreads, /*with_positions=*/half.ao || half.ssdo);
  const cv::Rect half_roi = half_grid_roi(r, full.depth_view.size());
  const cv::Rect term_roi =
      settings.denoise ? denoise_reads(half_roi, *settings.denoise, h.depth_view.size()) : half_roi;
  TermOutputs grid;
  GridInputs g;
  if (half.ao || half.ssdo) {
    g = half_grid_inputs(h, in, settings, half_grid_back_layer(h, in, settings, half.ao, out.views, nthreads),
                         nthreads);
    extend_grid_with_views(g, in, settings, out.views, nthreads);
  }
  std::vector<UpsampleImage> images;
  if (half.ao) {
    ao_on_grid(g, *settings.ao, term_roi, grid.ao, nthreads);
    if (!grid.ao.bent_normal_view.empty())
      images.push_back({grid.ao.bent_normal_view, out.ao.bent_normal_view, cv::Scalar(0, 0, 0), cv::Scalar(0, 0, 0),
                        UpsampleFinish::unit_vector});
  }
  if (half.ssdo) ssdo_on_grid(g, in, *settings.ssdo, term_roi, grid.ssdo, nthreads);
  HalfGridTerms raw{h, grid.ao.ao, grid.ssdo.direct, grid.ssdo.indirect};
  if (!settings.keep_grid_terms) add_raw_grid_terms(raw, out, images);
  if (settings.denoise)
    denoise_grid_terms(raw, *settings.denoise, half_roi, grid.denoised, out.denoised, images, nthreads);
  if (half.confidence) {
    // The views at the grid's density: the confidence's scattered asks read a quarter of
    // the memory for a fraction the grid's taps cannot resolve finer.
    const std::vector<DepthView> observers = views_at_density(
        confidence_observers(h.depth_view, h.mask, h.camera, in, settings, out.views, nthreads), h.camera.width_px,
        nthreads);
    compute_confidence(h.depth_view, h.normal_view, h.mask, h.camera, *settings.confidence, grid.confidence,
                       half_roi, nthreads, {observers, multiview_settings(settings)}, -on_half_grid(in.data_origin_px));
    images.push_back({grid.confidence, out.confidence, cv::Scalar(1.0), cv::Scalar(1.0)});
  }
  // The full-resolution images are allocated only now, after the kernels have freed their
  // scratch, the grid its inputs that the upsample does not read and the caller its own
  // (inputs_read): the heap hands that memory to them, where fresh pages would cost a fault
  // each on first touch.
  g = GridInputs();
  for (HalfGrid* grid_of : {&h, &raw.grid}) grid_of->position_view.release(), grid_of->source.release();
  if (inputs_read) inputs_read();
  allocate_upsampled(settings, half, full.depth_view.size(), out);
  upsample_from_half_grid(full, h, images, r, nthreads);
  if (settings.keep_grid_terms) out.grid = raw;
}

}  // namespace

MultiViewSettings multiview_settings(const TermSettings& settings) {
  MultiViewSettings m;
  const float radius = settings.ao           ? settings.ao->radius_world
                       : settings.ssdo       ? settings.ssdo->radius_world
                       : settings.confidence ? settings.confidence->radius_world
                                             : 1.0f;
  const float thickness = settings.ao     ? effective_thickness_world(*settings.ao)
                          : settings.ssdo ? settings.ssdo->thickness_world
                                          : kThicknessPerRadius * radius;
  m.thickness_world = std::isfinite(thickness) ? thickness : kThicknessPerRadius * radius;
  m.reach_world = 2.0f * radius;
  if (settings.ao) m.depth_bias_relative = settings.ao->depth_bias_relative;
  return m;
}

void compute_terms(const TermInputs& in, const TermSettings& settings, TermOutputs& out, cv::Rect roi,
                   int nthreads, const std::function<void()>& inputs_read) {
  CV_Assert(settings.ssdo == nullptr || in.environment != nullptr);
  const HalfTerms half = half_terms(settings);
  // Full-resolution positions only for a kernel that runs there.
  cv::Mat position_view = in.position_view;
  if (position_view.empty() && ((settings.ao && !half.ao) || (settings.ssdo && !half.ssdo)))
    view_positions_from_depth(in.depth_view, in.mask, in.camera, position_view, {}, nthreads);
  // The second depth layer at full resolution, for the kernels that run there.
  cv::Mat back;
  if ((settings.ao && !half.ao) || (settings.ssdo && !half.ssdo))
    back = grid_back_layer(in.depth_view, in.mask, in.camera,
                           in.depth_back_view != nullptr ? *in.depth_back_view : cv::Mat(), in, settings,
                           settings.ao && !half.ao, out.views, nthreads);
  if ((settings.ao && !half.ao) || (settings.ssdo && !half.ssdo)) {
    GridInputs g = full_grid_inputs(in, settings, position_view, back);
    extend_grid_with_views(g, in, settings, out.views, nthreads);
    const cv::Rect r = resolve_roi(roi, in.depth_view.size());
    if (settings.ao && !half.ao) ao_on_grid(g, *settings.ao, r, out.ao, nthreads);
    if (settings.ssdo && !half.ssdo) ssdo_on_grid(g, in, *settings.ssdo, r, out.ssdo, nthreads);
  }
  if (settings.confidence && !half.confidence) {
    const std::vector<DepthView> observers = confidence_observers(in.depth_view, in.mask, in.camera, in, settings,
                                                                  out.views, nthreads);
    compute_confidence(in.depth_view, in.normal_view, in.mask, in.camera, *settings.confidence, out.confidence,
                       roi, nthreads, {observers, multiview_settings(settings)}, -in.data_origin_px);
  }
  if (!half.any()) {
    if (inputs_read) inputs_read();
    return;
  }
  CV_Assert(in.depth_view.type() == CV_32FC1);
  CV_Assert(in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  CV_Assert(in.normal_view.type() == CV_32FC3 && in.normal_view.size() == in.depth_view.size());
  const cv::Rect r = resolve_roi(roi, in.depth_view.size());
  if (r.empty()) {
    if (inputs_read) inputs_read();
    return allocate_upsampled(settings, half, in.depth_view.size(), out);
  }
  const FullGrid full{in.depth_view, in.normal_view, position_view, in.mask, in.camera};
  // The upsample reads neither positions nor the second depth layer: their references go
  // with the caller's inputs.
  compute_on_half_grid(full, in, settings, half, out, r, nthreads, [&] {
    position_view.release();
    back.release();
    if (inputs_read) inputs_read();
  });
}

void finish_half_grid_terms(const FullGrid& full, const HalfGridTerms& raw, const HalfGridTerms& to_denoise,
                            const DenoiseSettings& settings, const HalfOutputs& stored_in_half, TermOutputs& out,
                            int nthreads) {
  if (raw.empty()) return;
  CV_Assert(to_denoise.ao.empty() == raw.ao.empty() && to_denoise.direct.empty() == raw.direct.empty());
  const cv::Size size = full.depth_view.size();
  const cv::Rect all(0, 0, size.width, size.height);
  std::vector<UpsampleImage> images;
  add_raw_grid_terms(raw, out, images);
  DenoisedTerms grid_denoised;
  denoise_grid_terms(to_denoise, settings, half_grid_roi(all, size), grid_denoised, out.denoised, images, nthreads);
  allocate_grid_terms(!raw.ao.empty(), !raw.direct.empty(), /*raw=*/true, /*denoised=*/true, stored_in_half, size,
                      out);
  upsample_from_half_grid(full, raw.grid, images, all, nthreads);
}

void compute_ao_at_resolution(const AoInputs& in, const AoSettings& settings, AoOutput& out, cv::Rect roi,
                              int nthreads) {
  const TermInputs terms{in.depth_view, in.normal_view, in.position_view, in.mask, in.camera, nullptr,
                         in.albedo, nullptr, in.depth_back_view};
  TermOutputs result;
  result.ao = std::move(out);  // the caller's images: only roi is written
  compute_terms(terms, {&settings, nullptr, nullptr}, result, roi, nthreads);
  out = std::move(result.ao);
}

void compute_ssdo_at_resolution(const SsdoInputs& in, const SsdoSettings& settings, SsdoOutput& out, cv::Rect roi,
                                int nthreads) {
  const TermInputs terms{in.depth_view, in.normal_view, in.position_view, in.mask, in.camera, &in.environment,
                         in.albedo, in.lighting, nullptr};
  TermOutputs result;
  result.ssdo = std::move(out);
  compute_terms(terms, {nullptr, &settings, nullptr}, result, roi, nthreads);
  out = std::move(result.ssdo);
}

void compute_confidence_at_resolution(const cv::Mat& depth_view, const cv::Mat& normal_view, const cv::Mat& mask,
                                      const Camera& camera, const ConfidenceSettings& settings,
                                      cv::Mat& confidence, cv::Rect roi, int nthreads) {
  const cv::Mat no_positions;  // the confidence reads none
  const TermInputs terms{depth_view, normal_view, no_positions, mask, camera};
  TermOutputs result;
  result.confidence = std::move(confidence);
  compute_terms(terms, {nullptr, nullptr, &settings}, result, roi, nthreads);
  confidence = std::move(result.confidence);
}

}  // namespace ssdo
#endif  // HWY_ONCE
