#include "kernels/half_resolution.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#if defined(__AVX2__) && defined(__FMA__) && defined(SSDO_HAVE_LIBMVEC)
#include <immintrin.h>
#define SSDO_HALF_RESOLUTION_AVX2 1
// glibc's vector math library (libmvec): expf in 8 AVX2 lanes, by its Vector Function ABI
// name (what GCC calls for a vectorised expf).
extern "C" __m256 _ZGVdN8v_expf(__m256 x);
#endif

#include "core/parallel.h"
#include "kernels/normals.h"
#include "kernels/positions.h"

namespace ssdo {

namespace {

// Depth tolerance of the upsample, relative to the pixel's depth: a texel whose depth
// differs by 5% of the pixel's weighs exp(-1) of one at the same depth, so the texels of a
// surface behind a silhouette (depth gaps are tens of percent) carry ~nothing across it.
constexpr float kUpsampleDepthRelative = 0.05f;

// Below this total weight the four texels are exp(-9)-small: the pixel's surface is not
// among them (a thin feature or a silhouette); ratios would amplify noise.
constexpr float kMinUpsampleWeight = 1e-4f;

constexpr int kMaxChannels = 4;

#if SSDO_HALF_RESOLUTION_AVX2
// exp(x) of the weights' depth term (x <= 0). With AVX2 the weights are computed 8 pixels
// at a time with libmvec's expf, and the per-pixel code calls the same function (one lane
// of it): a weight has the same bits whichever path computes it, so the output does not
// depend on rois or thread counts. On [-104, 0] libmvec's expf differs from std::exp in
// 4.4% of the floats, by at most 3 ulp (2^-21 relative): far below what a weight needs.
inline __m256 depth_falloff_8(__m256 x) { return _ZGVdN8v_expf(x); }
inline float depth_falloff(float x) { return _mm256_cvtss_f32(_ZGVdN8v_expf(_mm256_set1_ps(x))); }
#else
inline float depth_falloff(float x) { return std::exp(x); }
#endif

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
  parallel_rows(cv::Range(0, half.height), nthreads, [&](const cv::Range& rows) {
    for (int j = rows.start; j < rows.end; ++j)
      for (int i = 0; i < half.width; ++i) {
        int sx = -1, sy = -1;
        for (int k = 0; k < 4 && sx < 0; ++k) {
          const int x = 2 * i + (k & 1), y = 2 * j + (k >> 1);
          if (x < size.width && y < size.height && full.mask.ptr<uint8_t>(y)[x]) sx = x, sy = y;
        }
        h.source.ptr<cv::Vec2i>(j)[i] = cv::Vec2i(sx, sy);
        h.mask.ptr<uint8_t>(j)[i] = sx < 0 ? 0 : 255;
        if (sx < 0) {
          h.depth_view.ptr<float>(j)[i] = std::numeric_limits<float>::infinity();
          h.normal_view.ptr<cv::Vec3f>(j)[i] = cv::Vec3f(0, 0, 0);
          if (has_position) h.position_view.ptr<cv::Vec3f>(j)[i] = cv::Vec3f(0, 0, 0);
        } else {
          h.depth_view.ptr<float>(j)[i] = full.depth_view.ptr<float>(sy)[sx];
          h.normal_view.ptr<cv::Vec3f>(j)[i] = full.normal_view.ptr<cv::Vec3f>(sy)[sx];
          if (positions_given) {
            if (has_position) h.position_view.ptr<cv::Vec3f>(j)[i] = full.position_view.ptr<cv::Vec3f>(sy)[sx];
          } else if (has_position) {
            // As view_positions_from_depth at pixel (sx, sy).
            const glm::vec3 p = full.camera.view_from_pixel_depth({sx + 0.5f, sy + 0.5f},
                                                                  full.depth_view.ptr<float>(sy)[sx]);
            h.position_view.ptr<cv::Vec3f>(j)[i] = cv::Vec3f(p.x, p.y, p.z);
          }
        }
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

// out = sum_k w_k v_k / sum_k w_k over the texels of nonzero weight, in k order (masked
// texels, weight 0, are skipped: their values may be anything).
template <int C>
inline void blend(const cv::Mat& half, const Footprint& f, const float w[4], float wsum, float* out) {
  float acc[C] = {};
  for (int k = 0; k < 4; ++k) {
    if (w[k] == 0.0f) continue;
    const float* v = half.ptr<float>(f.y.t[k >> 1]) + size_t(f.x.t[k & 1]) * C;
    for (int ch = 0; ch < C; ++ch) acc[ch] += w[k] * v[ch];
  }
  for (int ch = 0; ch < C; ++ch) out[ch] = acc[ch] / wsum;
}

inline void blend_any(const cv::Mat& half, const Footprint& f, const float w[4], float wsum, float* out) {
  switch (half.channels()) {
    case 1: blend<1>(half, f, w, wsum, out); break;
    case 2: blend<2>(half, f, w, wsum, out); break;
    case 3: blend<3>(half, f, w, wsum, out); break;
    default: blend<4>(half, f, w, wsum, out); break;
  }
}
// Foreground pixel (x, y) of depth d and texel weights w of every image: the normalised
// blend, or the texel closest in depth, or the fallback (header).
void upsample_pixel(const HalfGrid& h, std::span<const UpsampleImage> images, const Footprint& f, float d,
                    const float w[4], int x, int y) {
  float wsum = 0.0f;
  for (int k = 0; k < 4; ++k) wsum += w[k];
  if (!(wsum > kMinUpsampleWeight)) {
    int bi, bj;
    if (!nearest_in_depth(h, f, d, bi, bj)) {  // no foreground texel near: nothing known
      for (const UpsampleImage& im : images)
        write_scalar(im.full.ptr<float>(y) + size_t(x) * size_t(im.full.channels()), im.fallback,
                     im.full.channels());
      return;
    }
    for (const UpsampleImage& im : images) {
      const int cn = im.half.channels();
      std::copy_n(im.half.ptr<float>(bj) + size_t(bi) * size_t(cn), cn, im.full.ptr<float>(y) + size_t(x) * size_t(cn));
    }
    return;
  }
  for (const UpsampleImage& im : images)
    blend_any(im.half, f, w, wsum, im.full.ptr<float>(y) + size_t(x) * size_t(im.half.channels()));
}

// Pixels [x0, x1) of row y of every image.
void upsample_span(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images, int y,
                   const AxisFootprint& fy, int x0, int x1) {
  const uint8_t* mask_row = full.mask.ptr<uint8_t>(y);
  Footprint f;
  f.y = fy;
  for (int x = x0; x < x1; ++x) {
    if (!mask_row[x]) {
      for (const UpsampleImage& im : images)
        write_scalar(im.full.ptr<float>(y) + size_t(x) * size_t(im.full.channels()), im.background,
                     im.full.channels());
      continue;
    }
    const float d = full.depth_view.ptr<float>(y)[x];
    f.x = axis_footprint(x, h.depth_view.cols);
    float w[4];
    texel_weights(h, f, d, full.normal_view.ptr<cv::Vec3f>(y)[x], w);
    upsample_pixel(h, images, f, d, w, x, y);
  }
}

// Rows per strip of the upsample: a strip lays out each texel row it reads once
// (TexelRows), and pixel rows 2j + 1 and 2j + 2 read the same two texel rows.
constexpr int kRowsPerStrip = 16;

#ifdef SSDO_HALF_RESOLUTION_AVX2
// Eight pixels at a time (AVX2, FMA): the same operations as the per-pixel code in the
// same order, lane by lane, so the same bits. Pixel x (odd) .. x + 7 read texel columns
// m .. m + 4, m = (x - 1) / 2: pixels 2m + 1 and 2m + 2 both read texels m and m + 1, with
// bilinear fractions 0.25 and 0.75 (exact in float for widths below 2^22).
namespace lanes {

constexpr int kMaxWidth = 1 << 22;

// x, y, z of 8 interleaved 3-vectors (24 floats) and back.
inline void deinterleave_3(const float* p, __m256& x, __m256& y, __m256& z) {
  const __m256 a = _mm256_loadu_ps(p), b = _mm256_loadu_ps(p + 8), c = _mm256_loadu_ps(p + 16);
  x = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a, b, 0b10010010), c, 0b00100100),
                               _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
  y = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a, b, 0b00100100), c, 0b01001001),
                               _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6));
  z = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a, b, 0b01001001), c, 0b10010010),
                               _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
}

inline void interleave_3(__m256 x, __m256 y, __m256 z, float* p) {
  x = _mm256_permutevar8x32_ps(x, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
  y = _mm256_permutevar8x32_ps(y, _mm256_setr_epi32(5, 0, 3, 6, 1, 4, 7, 2));
  z = _mm256_permutevar8x32_ps(z, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
  _mm256_storeu_ps(p, _mm256_blend_ps(_mm256_blend_ps(x, y, 0b10010010), z, 0b00100100));
  _mm256_storeu_ps(p + 8, _mm256_blend_ps(_mm256_blend_ps(x, y, 0b00100100), z, 0b01001001));
  _mm256_storeu_ps(p + 16, _mm256_blend_ps(_mm256_blend_ps(x, y, 0b01001001), z, 0b10010010));
}

// All-ones lanes where the 8 mask bytes are nonzero.
inline __m256 foreground(const uint8_t* mask) {
  const __m256i m = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(mask)));
  return _mm256_castsi256_ps(_mm256_cmpgt_epi32(m, _mm256_setzero_si256()));
}

// Texel rows of the half grid laid out for 8 pixels at a time: per row, one array per
// quantity (the depth, the normal's x, y, z and the mask as all-ones or zero
// bits; then each image's channels), indexed by texel column + 1, the edge texels repeated
// at 0 and hw + 1 (axis_footprint's clamp). The texels of pixels x .. x + 7 are then lanes
// 0 .. 4 of each array from m + 1, and a strip fills each row it reads once.
class TexelRows {
 public:
  static constexpr int kDepth = 0, kNormalX = 1, kNormalY = 2, kNormalZ = 3, kMask = 4;

  TexelRows(const HalfGrid& h, std::span<const UpsampleImage> images)
      : h_(h), images_(images), hw_(h.depth_view.cols), length_(hw_ + 2 + 8) {
    int arrays = kMask + 1;
    for (const UpsampleImage& im : images) {
      image_first_.push_back(arrays);
      arrays += im.half.channels();
    }
    arrays_ = arrays;
    data_.assign(size_t(2) * size_t(arrays_) * size_t(length_), 0.0f);
  }

  int length() const { return length_; }
  int image_first(size_t i) const { return image_first_[i]; }

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
  int slot_of(int j) const { return row_[0] == j ? 0 : row_[1] == j ? 1 : -1; }
  float* slot(int s) { return data_.data() + size_t(s) * size_t(arrays_) * size_t(length_); }

  void fill_array(float* a, const float* src, int step) {
    for (int i = 0; i < hw_; ++i) a[i + 1] = src[size_t(i) * size_t(step)];
    a[0] = a[1];
    a[hw_ + 1] = a[hw_];
  }

  void fill(int s, int j) {
    float* base = slot(s);
    fill_array(base + kDepth * length_, h_.depth_view.ptr<float>(j), 1);
    const float* n = h_.normal_view.ptr<float>(j);
    for (int c = 0; c < 3; ++c) fill_array(base + (kNormalX + c) * length_, n + c, 3);
    const uint8_t* m = h_.mask.ptr<uint8_t>(j);
    float* a = base + kMask * length_;
    for (int i = 0; i < hw_; ++i) a[i + 1] = std::bit_cast<float>(m[i] ? ~uint32_t(0) : uint32_t(0));
    a[0] = a[1];
    a[hw_ + 1] = a[hw_];
    for (size_t k = 0; k < images_.size(); ++k) {
      const int cn = images_[k].half.channels();
      const float* v = images_[k].half.ptr<float>(j);
      for (int c = 0; c < cn; ++c) fill_array(base + (image_first_[k] + c) * length_, v + c, cn);
    }
    row_[s] = j;
  }

  const HalfGrid& h_;
  std::span<const UpsampleImage> images_;
  int hw_, length_, arrays_ = 0;
  std::vector<int> image_first_;
  std::vector<float> data_;
  int row_[2] = {-1, -1};
};

// The texels of pixels x .. x + 7 (x odd) from one array of TexelRows: column t[0] of each
// pixel (kFirst) or t[1] (kSecond).
inline __m256 texel_lanes(const float* array, int x, __m256i column) {
  return _mm256_permutevar8x32_ps(_mm256_loadu_ps(array + (x - 1) / 2 + 1), column);
}

inline __m256i column_lanes(int k) {
  return (k & 1) ? _mm256_setr_epi32(1, 1, 2, 2, 3, 3, 4, 4) : _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3);
}

// texel_weights of the 8 pixels x .. x + 7 (x odd) of a row whose texel rows are r0, r1
// (TexelRows) and vertical bilinear weights wy; 0 where `foreground` is not.
inline void texel_weights_8(const float* r0, const float* r1, int length, const float wy[2], int x,
                            const float* depth_row, const float* normal_row, __m256 foreground, __m256 w[4]) {
  const __m256 zero = _mm256_setzero_ps(), sign = _mm256_set1_ps(-0.0f);
  const __m256 d = _mm256_loadu_ps(depth_row + x);
  __m256 nx, ny, nz;
  deinterleave_3(normal_row + size_t(3) * size_t(x), nx, ny, nz);
  const __m256 inv_tol = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_mul_ps(_mm256_set1_ps(kUpsampleDepthRelative), d));
  const __m256 frac_x = _mm256_setr_ps(0.25f, 0.75f, 0.25f, 0.75f, 0.25f, 0.75f, 0.25f, 0.75f);
  const __m256 wx[2] = {_mm256_sub_ps(_mm256_set1_ps(1.0f), frac_x), frac_x};
  for (int k = 0; k < 4; ++k) {
    const float* row = (k >> 1) ? r1 : r0;
    const __m256i column = column_lanes(k);
    const __m256 valid = _mm256_and_ps(foreground, texel_lanes(row + TexelRows::kMask * length, x, column));
    const __m256 wb = _mm256_mul_ps(wx[k & 1], _mm256_set1_ps(wy[k >> 1]));
    const __m256 texel_depth = texel_lanes(row + TexelRows::kDepth * length, x, column);
    const __m256 dz = _mm256_mul_ps(_mm256_andnot_ps(sign, _mm256_sub_ps(texel_depth, d)), inv_tol);
    // exp(-dz); 0 (exp = 1, the weight set to 0 below) where the weight is 0.
    const __m256 e = depth_falloff_8(_mm256_and_ps(valid, _mm256_xor_ps(dz, sign)));
    __m256 c = _mm256_add_ps(zero, _mm256_mul_ps(nx, texel_lanes(row + TexelRows::kNormalX * length, x, column)));
    c = _mm256_add_ps(c, _mm256_mul_ps(ny, texel_lanes(row + TexelRows::kNormalY * length, x, column)));
    c = _mm256_add_ps(c, _mm256_mul_ps(nz, texel_lanes(row + TexelRows::kNormalZ * length, x, column)));
    c = _mm256_max_ps(c, zero);  // c > 0 ? c : 0, as std::max(0, c)
    c = _mm256_mul_ps(c, c);
    w[k] = _mm256_and_ps(valid, _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(wb, e), c), c));
  }
}

// What the 8-pixel code of pixel row y reads: its two texel rows (from `texels`), their
// vertical bilinear weights and the row's full-resolution guides.
struct PixelRow {
  const float* r0;
  const float* r1;
  int length;  // TexelRows::length()
  float wy[2];
  const float* depth;
  const float* normal;
  const uint8_t* mask;

  PixelRow(TexelRows& texels, const FullGrid& full, int y, const AxisFootprint& fy)
      : length(texels.length()),
        wy{1.0f - fy.frac, fy.frac},
        depth(full.depth_view.ptr<float>(y)),
        normal(full.normal_view.ptr<float>(y)),
        mask(full.mask.ptr<uint8_t>(y)) {
    texels.rows(fy.t[0], fy.t[1], r0, r1);
  }

  // texel_weights_8 of pixels x .. x + 7, 0 where `fg` is not.
  void weights(int x, __m256 fg, __m256 w[4]) const {
    texel_weights_8(r0, r1, length, wy, x, depth, normal, fg, w);
  }
};

}  // namespace lanes
#endif

// The pixels of row y in [x0, x1) that the 8-pixel code takes: from the first odd x, whole
// groups of 8 (the others go pixel by pixel).
struct LaneSpan {
  int begin, end;
};

inline LaneSpan lane_span(int x0, int x1, int width) {
#ifdef SSDO_HALF_RESOLUTION_AVX2
  if (width < lanes::kMaxWidth) {
    const int begin = std::max(x0, 1) | 1;
    if (begin + 8 <= x1) return {begin, begin + (x1 - begin) / 8 * 8};
  }
#endif
  (void)x0, (void)width;
  return {x1, x1};
}

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
    CV_Assert(im.full.type() == im.half.type() && im.full.size() == full.depth_view.size());
    CV_Assert(im.half.channels() <= kMaxChannels);
  }
  const LaneSpan span = lane_span(r.x, r.x + r.width, full.depth_view.cols);
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
#ifdef SSDO_HALF_RESOLUTION_AVX2
    lanes::TexelRows texels(h, images);
#endif
    for (int y = rows.start; y < rows.end; ++y) {
      const AxisFootprint fy = axis_footprint(y, hh);
      upsample_span(full, h, images, y, fy, r.x, span.begin);
#ifdef SSDO_HALF_RESOLUTION_AVX2
      if (span.begin < span.end) {
        const lanes::PixelRow row(texels, full, y, fy);
        const __m256 zero = _mm256_setzero_ps();
        for (int x = span.begin; x < span.end; x += 8) {
          const __m256 fg = lanes::foreground(row.mask + x);
          __m256 w[4];
          row.weights(x, fg, w);
          __m256 wsum = zero;
          for (int k = 0; k < 4; ++k) wsum = _mm256_add_ps(wsum, w[k]);
          // Foreground pixels whose weights are too small go pixel by pixel (below).
          const int low = _mm256_movemask_ps(
              _mm256_andnot_ps(_mm256_cmp_ps(wsum, _mm256_set1_ps(kMinUpsampleWeight), _CMP_GT_OQ), fg));
          __m256 used[4];  // texels of nonzero weight (blend skips the others)
          for (int k = 0; k < 4; ++k) used[k] = _mm256_cmp_ps(w[k], zero, _CMP_NEQ_UQ);
          for (size_t i = 0; i < images.size(); ++i) {
            const UpsampleImage& im = images[i];
            const int cn = im.half.channels();
            __m256 value[kMaxChannels];
            for (int ch = 0; ch < cn; ++ch) {
              const int a = (texels.image_first(i) + ch) * row.length;
              __m256 acc = zero;
              for (int k = 0; k < 4; ++k) {
                const __m256 v = lanes::texel_lanes(((k >> 1) ? row.r1 : row.r0) + a, x, lanes::column_lanes(k));
                acc = _mm256_blendv_ps(acc, _mm256_add_ps(acc, _mm256_mul_ps(w[k], v)), used[k]);
              }
              value[ch] = _mm256_blendv_ps(_mm256_set1_ps(float(im.background[ch])), _mm256_div_ps(acc, wsum), fg);
            }
            float* out = im.full.ptr<float>(y) + size_t(x) * size_t(cn);
            if (cn == 1) {
              _mm256_storeu_ps(out, value[0]);
            } else if (cn == 3) {
              lanes::interleave_3(value[0], value[1], value[2], out);
            } else {
              alignas(32) float v[kMaxChannels][8];
              for (int ch = 0; ch < cn; ++ch) _mm256_store_ps(v[ch], value[ch]);
              for (int l = 0; l < 8; ++l)
                for (int ch = 0; ch < cn; ++ch) out[l * cn + ch] = v[ch][l];
            }
          }
          if (low != 0) {
            alignas(32) float wl[4][8];
            for (int k = 0; k < 4; ++k) _mm256_store_ps(wl[k], w[k]);
            Footprint f;
            f.y = fy;
            for (int l = 0; l < 8; ++l) {
              if (!(low & (1 << l))) continue;
              f.x = axis_footprint(x + l, h.depth_view.cols);
              const float wp[4] = {wl[0][l], wl[1][l], wl[2][l], wl[3][l]};
              upsample_pixel(h, images, f, row.depth[x + l], wp, x + l, y);
            }
          }
        }
      }
#endif
      upsample_span(full, h, images, y, fy, span.end, r.x + r.width);
    }
  }, kRowsPerStrip);
}

float upsample_depth_falloff(float x) { return depth_falloff(x); }

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

// The full-resolution images the upsample writes, as the kernels allocate their outputs.
void allocate_upsampled(const TermSettings& settings, const HalfTerms& half, const cv::Size& size,
                        TermOutputs& out) {
  if (half.ao) {
    allocate(out.ao.ao, size, CV_32FC1);
    if (has_bent_normal(*settings.ao)) allocate(out.ao.bent_normal_view, size, CV_32FC3);
    else out.ao.bent_normal_view.release();
  }
  if (half.ssdo) {
    allocate(out.ssdo.direct, size, CV_32FC3);
    allocate(out.ssdo.indirect, size, CV_32FC3);
  }
  if (half.confidence) allocate(out.confidence, size, CV_32FC1);
}

// The second depth layer on a grid (depth, mask, camera of the grid; `file_back` the
// frame's own layer on that grid, or empty): the occupancy of all views when there are
// views, else the file's layer. Empty when neither.
cv::Mat grid_back_layer(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                        const cv::Mat& file_back, const TermInputs& in, const TermSettings& settings,
                        std::vector<ViewUse>& uses, int nthreads) {
  if (in.views.empty()) return file_back;
  cv::Mat back;
  const MultiViewInputs grid{depth_view, mask, camera, file_back.empty() ? nullptr : &file_back};
  uses = occupancy_from_views(grid, in.views, multiview_settings(settings), back, nthreads);
  return back.empty() ? file_back : back;
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
cv::Mat half_grid_back_layer(const HalfGrid& h, const TermInputs& in, const TermSettings& settings,
                             std::vector<ViewUse>& uses, int nthreads) {
  cv::Mat file_back;
  if (in.depth_back_view != nullptr && !in.depth_back_view->empty())
    sample_at_texels(h, *in.depth_back_view, file_back, nthreads);
  return grid_back_layer(h.depth_view, h.mask, h.camera, file_back, in, settings, uses, nthreads);
}

// One grid's inputs to AO and SSDO: the half grid's texels or the full-resolution images,
// extended by a guard band of off-screen texels when the views saw past the edges (the
// frame's grid then starts at `origin` in these images).
struct GridInputs {
  cv::Mat depth_view, normal_view, position_view, mask;
  Camera camera;
  cv::Mat albedo, lighting, back;  // empty when the kernels do not read them
  cv::Point origin{0, 0};
};

// Whether AO's multi-bounce or SSDO's senders read the albedo, and SSDO the lighting.
bool reads_albedo(const TermInputs& in, const TermSettings& s) {
  const bool lit = in.lighting != nullptr && !in.lighting->empty();
  return in.albedo != nullptr && !in.albedo->empty() && ((s.ao && s.ao->multibounce) || (s.ssdo && !lit));
}
bool reads_lighting(const TermInputs& in, const TermSettings& s) {
  return s.ssdo && in.lighting != nullptr && !in.lighting->empty();
}

GridInputs half_grid_inputs(const HalfGrid& h, const TermInputs& in, const TermSettings& s, const cv::Mat& back,
                            int nthreads) {
  GridInputs g{h.depth_view, h.normal_view, h.position_view, h.mask, h.camera, {}, {}, back};
  if (reads_albedo(in, s)) sample_at_texels(h, *in.albedo, g.albedo, nthreads);
  if (reads_lighting(in, s)) sample_at_texels(h, *in.lighting, g.lighting, nthreads);
  return g;
}

GridInputs full_grid_inputs(const TermInputs& in, const TermSettings& s, const cv::Mat& position_view,
                            const cv::Mat& back) {
  GridInputs g{in.depth_view, in.normal_view, position_view, in.mask, in.camera, {}, {}, back};
  if (reads_albedo(in, s)) g.albedo = *in.albedo;
  if (reads_lighting(in, s)) g.lighting = *in.lighting;
  return g;
}

// The grid extended by the guard band (kernels/multiview.h) when some view is used and taps
// leave the picture. Band texels get positions and normals reconstructed from the views'
// depth, and no albedo or lighting (0: a sender the frame has no light for stays dark).
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
  const int margin = band.margin_px;
  if (margin == 0) return;
  const cv::Rect inside = band.inside();
  const auto pad = [margin](cv::Mat& image) {
    if (!image.empty()) cv::copyMakeBorder(image, image, margin, margin, margin, margin, cv::BORDER_CONSTANT, 0);
  };
  pad(g.normal_view);
  pad(g.position_view);
  pad(g.albedo);
  pad(g.lighting);
  const int w = band.camera.width_px, h = band.camera.height_px;
  for (const cv::Rect& side : {cv::Rect(0, 0, w, margin), cv::Rect(0, h - margin, w, margin),
                               cv::Rect(0, margin, margin, inside.height), cv::Rect(w - margin, margin, margin, inside.height)}) {
    reconstruct_normals_from_depth(band.depth_view, band.mask, band.camera, g.normal_view, side, nthreads);
    if (!g.position_view.empty())
      view_positions_from_depth(band.depth_view, band.mask, band.camera, g.position_view, side, nthreads);
  }
  g.depth_view = band.depth_view;
  g.mask = band.mask;
  g.back = band.depth_back_view;
  g.camera = band.camera;
  g.origin = {margin, margin};
}

// `roi` of the grid's own images from the extended images (only roi is written, as the
// kernels write; `out` allocated at the grid's size when needed).
void crop_from_band(const cv::Mat& extended, const GridInputs& g, const cv::Rect& roi, cv::Mat& out) {
  if (extended.empty()) {
    out.release();
    return;
  }
  const cv::Size size(g.camera.width_px - 2 * g.origin.x, g.camera.height_px - 2 * g.origin.y);
  if (out.size() != size || out.type() != extended.type()) out.create(size, extended.type());
  extended(roi + g.origin).copyTo(out(roi));
}

// AO on the grid's pixels of roi.
void ao_on_grid(const GridInputs& g, const AoSettings& s, const cv::Rect& roi, AoOutput& out, int nthreads) {
  const AoInputs grid{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera,
                      g.albedo.empty() ? nullptr : &g.albedo, g.back.empty() ? nullptr : &g.back, g.origin};
  if (g.origin == cv::Point(0, 0)) return compute_ao(grid, s, out, roi, nthreads);
  AoOutput extended;
  compute_ao(grid, s, extended, roi + g.origin, nthreads);
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
                        g.back.empty() ? nullptr : &g.back, g.origin};
  if (g.origin == cv::Point(0, 0)) return compute_ssdo(grid, s, out, roi, nthreads);
  SsdoOutput extended;
  compute_ssdo(grid, s, extended, roi + g.origin, nthreads);
  crop_from_band(extended.direct, g, roi, out.direct);
  crop_from_band(extended.indirect, g, roi, out.indirect);
}

// A weighted mean of AO values stays in [0, 1] up to rounding; of unit bent normals it is
// shorter than 1: renormalised (zero length: the pixel's normal).
void finish_upsampled_ao(const TermInputs& in, AoOutput& out, const cv::Rect& r, int nthreads) {
  const bool has_bent_normal = !out.bent_normal_view.empty();
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* ao_row = out.ao.ptr<float>(y);
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        ao_row[x] = std::clamp(ao_row[x], 0.0f, 1.0f);
        if (!has_bent_normal || !mask_row[x]) continue;
        cv::Vec3f& b = out.bent_normal_view.ptr<cv::Vec3f>(y)[x];
        const float len = float(cv::norm(b));
        b = len > 1e-12f ? b * (1.0f / len) : in.normal_view.ptr<cv::Vec3f>(y)[x];
      }
    }
  });
}

// The terms that run on the half grid: the grid (with positions when AO or SSDO runs on
// it), each kernel on the texels the upsample of r reads, then one upsample of all their
// images. Background and no foreground texel near: AO 1 (unoccluded), bent normal 0 (set
// to the normal by finish_upsampled_ao), SSDO 0 (nothing known of the light), confidence 1.
void compute_on_half_grid(const FullGrid& full, const TermInputs& in, const TermSettings& settings,
                          const HalfTerms& half, TermOutputs& out, const cv::Rect& r, int nthreads) {
  HalfGrid h;
  build_half_grid(full, h, nthreads, /*with_positions=*/half.ao || half.ssdo);
  const cv::Rect half_roi = half_grid_roi(r, full.depth_view.size());
  TermOutputs grid;
  GridInputs g;
  if (half.ao || half.ssdo) {
    g = half_grid_inputs(h, in, settings, half_grid_back_layer(h, in, settings, out.views, nthreads), nthreads);
    extend_grid_with_views(g, in, settings, out.views, nthreads);
  }
  std::vector<UpsampleImage> images;
  if (half.ao) {
    ao_on_grid(g, *settings.ao, half_roi, grid.ao, nthreads);
    images.push_back({grid.ao.ao, out.ao.ao, cv::Scalar(1.0), cv::Scalar(1.0)});
    if (!grid.ao.bent_normal_view.empty())
      images.push_back({grid.ao.bent_normal_view, out.ao.bent_normal_view, cv::Scalar(0, 0, 0), cv::Scalar(0, 0, 0)});
  }
  if (half.ssdo) {
    ssdo_on_grid(g, in, *settings.ssdo, half_roi, grid.ssdo, nthreads);
    images.push_back({grid.ssdo.direct, out.ssdo.direct, cv::Scalar::all(0), cv::Scalar::all(0)});
    images.push_back({grid.ssdo.indirect, out.ssdo.indirect, cv::Scalar::all(0), cv::Scalar::all(0)});
  }
  if (half.confidence) {
    // The views at the grid's density: the confidence's scattered asks read a quarter of
    // the memory for a fraction the grid's taps cannot resolve finer.
    const std::vector<DepthView> observers = views_at_density(
        confidence_observers(h.depth_view, h.mask, h.camera, in, settings, out.views, nthreads), h.camera.width_px,
        nthreads);
    compute_confidence(h.depth_view, h.normal_view, h.mask, h.camera, *settings.confidence, grid.confidence,
                       half_roi, nthreads, {observers, multiview_settings(settings)});
    images.push_back({grid.confidence, out.confidence, cv::Scalar(1.0), cv::Scalar(1.0)});
  }
  upsample_from_half_grid(full, h, images, r, nthreads);
  if (half.ao) finish_upsampled_ao(in, out.ao, r, nthreads);
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
                   int nthreads) {
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
                           in.depth_back_view != nullptr ? *in.depth_back_view : cv::Mat(), in, settings, out.views,
                           nthreads);
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
                       roi, nthreads, {observers, multiview_settings(settings)});
  }
  if (!half.any()) return;
  CV_Assert(in.depth_view.type() == CV_32FC1);
  CV_Assert(in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  CV_Assert(in.normal_view.type() == CV_32FC3 && in.normal_view.size() == in.depth_view.size());
  allocate_upsampled(settings, half, in.depth_view.size(), out);
  const cv::Rect r = resolve_roi(roi, in.depth_view.size());
  if (r.empty()) return;
  const FullGrid full{in.depth_view, in.normal_view, position_view, in.mask, in.camera};
  compute_on_half_grid(full, in, settings, half, out, r, nthreads);
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
