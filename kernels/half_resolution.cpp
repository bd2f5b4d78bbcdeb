#include "kernels/half_resolution.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "kernels/parallel.h"

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

void write_scalar(float* dst, const cv::Scalar& v, int channels) {
  for (int ch = 0; ch < channels; ++ch) dst[ch] = float(v[ch]);
}

}  // namespace

void build_half_grid(const FullGrid& full, std::span<const cv::Mat* const> extras, HalfGrid& h,
                     int nthreads) {
  const cv::Size size = full.depth_view.size();
  const cv::Size half((size.width + 1) / 2, (size.height + 1) / 2);
  h.depth_view.create(half, CV_32FC1);
  h.normal_view.create(half, CV_32FC3);
  const bool has_position = !full.position_view.empty();
  if (has_position) h.position_view.create(half, CV_32FC3);
  else h.position_view.release();
  h.mask.create(half, CV_8UC1);
  h.source.create(half, CV_32SC2);
  h.extras.assign(extras.size(), cv::Mat());
  for (const cv::Mat* e : extras) CV_Assert(!e || e->empty() || (e->depth() == CV_32F && e->size() == size));
  h.upsample_weights.release();
  h.upsample_roi = {};
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
          if (has_position) h.position_view.ptr<cv::Vec3f>(j)[i] = full.position_view.ptr<cv::Vec3f>(sy)[sx];
        }
      }
  });
  for (size_t e = 0; e < extras.size(); ++e)
    if (extras[e] && !extras[e]->empty()) sample_at_texels(h, *extras[e], h.extras[e], nthreads);
}

const HalfGrid& shared_or_own_half_grid(const FullGrid& full, const HalfGrid* shared, HalfGrid& own,
                                        bool need_positions, int nthreads) {
  if (shared == nullptr) {
    build_half_grid(full, {}, own, nthreads);
    return own;
  }
  const cv::Size size = full.depth_view.size();
  CV_Assert(shared->depth_view.size() == cv::Size((size.width + 1) / 2, (size.height + 1) / 2));
  CV_Assert(!need_positions || !shared->position_view.empty());
  return *shared;
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
    w[k] = wb * std::exp(-dz) * c * c;
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

void build_upsample_weights(const FullGrid& full, HalfGrid& h, cv::Rect roi, int nthreads) {
  const cv::Rect r = roi.empty() ? cv::Rect(cv::Point(), full.depth_view.size())
                                 : roi & cv::Rect(cv::Point(), full.depth_view.size());
  h.upsample_weights.create(full.depth_view.size(), CV_32FC4);
  h.upsample_roi = r;
  const int hw = h.depth_view.cols, hh = h.depth_view.rows;
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = full.mask.ptr<uint8_t>(y);
      cv::Vec4f* out = h.upsample_weights.ptr<cv::Vec4f>(y);
      Footprint f;
      f.y = axis_footprint(y, hh);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!mask_row[x]) {
          out[x] = cv::Vec4f(0, 0, 0, 0);
          continue;
        }
        f.x = axis_footprint(x, hw);
        texel_weights(h, f, full.depth_view.ptr<float>(y)[x], full.normal_view.ptr<cv::Vec3f>(y)[x], &out[x][0]);
      }
    }
  });
}

void upsample_from_half_grid(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images,
                             const cv::Rect& r, int nthreads) {
  const int hw = h.depth_view.cols, hh = h.depth_view.rows;
  for (const UpsampleImage& im : images) {
    CV_Assert(im.half.depth() == CV_32F && im.half.size() == h.depth_view.size());
    CV_Assert(im.full.type() == im.half.type() && im.full.size() == full.depth_view.size());
    CV_Assert(im.half.channels() <= kMaxChannels);
  }
  const bool kept = !h.upsample_weights.empty() && h.upsample_weights.size() == full.depth_view.size() &&
                    (h.upsample_roi & r) == r;
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = full.mask.ptr<uint8_t>(y);
      const cv::Vec4f* kept_row = kept ? h.upsample_weights.ptr<cv::Vec4f>(y) : nullptr;
      Footprint f;
      f.y = axis_footprint(y, hh);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!mask_row[x]) {
          for (const UpsampleImage& im : images)
            write_scalar(im.full.ptr<float>(y) + size_t(x) * size_t(im.full.channels()), im.background,
                         im.full.channels());
          continue;
        }
        const float d = full.depth_view.ptr<float>(y)[x];
        f.x = axis_footprint(x, hw);
        float w[4];
        if (kept) std::copy_n(&kept_row[x][0], 4, w);
        else texel_weights(h, f, d, full.normal_view.ptr<cv::Vec3f>(y)[x], w);
        float wsum = 0.0f;
        for (int k = 0; k < 4; ++k) wsum += w[k];
        if (!(wsum > kMinUpsampleWeight)) {
          int bi, bj;
          if (!nearest_in_depth(h, f, d, bi, bj)) {  // no foreground texel near: nothing known
            for (const UpsampleImage& im : images)
              write_scalar(im.full.ptr<float>(y) + size_t(x) * size_t(im.full.channels()), im.fallback,
                           im.full.channels());
            continue;
          }
          for (const UpsampleImage& im : images) {
            const int cn = im.half.channels();
            std::copy_n(im.half.ptr<float>(bj) + size_t(bi) * size_t(cn), cn,
                        im.full.ptr<float>(y) + size_t(x) * size_t(cn));
          }
          continue;
        }
        for (const UpsampleImage& im : images)
          blend_any(im.half, f, w, wsum, im.full.ptr<float>(y) + size_t(x) * size_t(im.half.channels()));
      }
    }
  });
}

}  // namespace ssdo
