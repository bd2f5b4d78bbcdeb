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
  for (size_t e = 0; e < extras.size(); ++e) {
    if (!extras[e] || extras[e]->empty()) continue;
    CV_Assert(extras[e]->depth() == CV_32F && extras[e]->size() == size);
    h.extras[e].create(half, extras[e]->type());
  }
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
        for (size_t e = 0; e < extras.size(); ++e) {
          cv::Mat& dst = h.extras[e];
          if (dst.empty()) continue;
          const int cn = dst.channels();
          float* d = dst.ptr<float>(j) + size_t(i) * size_t(cn);
          if (sx < 0) std::fill(d, d + cn, 0.0f);
          else std::copy_n(extras[e]->ptr<float>(sy) + size_t(sx) * size_t(cn), cn, d);
        }
      }
  });
}

cv::Rect half_grid_roi(const cv::Rect& r, const cv::Size& size) {
  // Pixel x reads texels floor(x / 2 - 0.25) - 1 .. + 2.
  return cv::Rect(r.x / 2 - 2, r.y / 2 - 2, r.width / 2 + 5, r.height / 2 + 5) &
         cv::Rect(0, 0, (size.width + 1) / 2, (size.height + 1) / 2);
}

void upsample_from_half_grid(const FullGrid& full, const HalfGrid& h, std::span<const UpsampleImage> images,
                             const cv::Rect& r, int nthreads) {
  const int hw = h.depth_view.cols, hh = h.depth_view.rows;
  for (const UpsampleImage& im : images) {
    CV_Assert(im.half.depth() == CV_32F && im.half.size() == h.depth_view.size());
    CV_Assert(im.full.type() == im.half.type() && im.full.size() == full.depth_view.size());
    CV_Assert(im.half.channels() <= kMaxChannels);
  }
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = full.mask.ptr<uint8_t>(y);
      const float fy = (float(y) + 0.5f) * 0.5f - 0.5f;
      const int j0 = int(std::floor(fy));
      const float wy1 = fy - float(j0);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!mask_row[x]) {
          for (const UpsampleImage& im : images)
            write_scalar(im.full.ptr<float>(y) + size_t(x) * size_t(im.full.channels()), im.background,
                         im.full.channels());
          continue;
        }
        const float d = full.depth_view.ptr<float>(y)[x];
        const cv::Vec3f n = full.normal_view.ptr<cv::Vec3f>(y)[x];
        const float inv_tol = 1.0f / (kUpsampleDepthRelative * d);
        const float fx = (float(x) + 0.5f) * 0.5f - 0.5f;
        const int i0 = int(std::floor(fx));
        const float wx1 = fx - float(i0);
        // The texels and their weights.
        int ti[4], tj[4];
        float tw[4];
        int n_taps = 0;
        float wsum = 0.0f;
        for (int k = 0; k < 4; ++k) {
          const int i = std::clamp(i0 + (k & 1), 0, hw - 1), j = std::clamp(j0 + (k >> 1), 0, hh - 1);
          if (!h.mask.ptr<uint8_t>(j)[i]) continue;
          const float wb = ((k & 1) ? wx1 : 1.0f - wx1) * ((k >> 1) ? wy1 : 1.0f - wy1);
          const float dz = std::abs(h.depth_view.ptr<float>(j)[i] - d) * inv_tol;
          float c = std::max(0.0f, n.dot(h.normal_view.ptr<cv::Vec3f>(j)[i]));
          c *= c;
          const float w = wb * std::exp(-dz) * c * c;
          ti[n_taps] = i, tj[n_taps] = j, tw[n_taps] = w;
          ++n_taps;
          wsum += w;
        }
        if (!(wsum > kMinUpsampleWeight)) {
          int bi = -1, bj = -1;
          float best = std::numeric_limits<float>::infinity();
          for (int dj = -1; dj <= 2; ++dj)
            for (int di = -1; di <= 2; ++di) {
              const int i = i0 + di, j = j0 + dj;
              if (i < 0 || j < 0 || i >= hw || j >= hh || !h.mask.ptr<uint8_t>(j)[i]) continue;
              const float dz = std::abs(h.depth_view.ptr<float>(j)[i] - d);
              if (dz < best) best = dz, bi = i, bj = j;
            }
          if (bi < 0) {  // no foreground texel near: nothing known
            for (const UpsampleImage& im : images)
              write_scalar(im.full.ptr<float>(y) + size_t(x) * size_t(im.full.channels()), im.fallback,
                           im.full.channels());
            continue;
          }
          n_taps = 1, ti[0] = bi, tj[0] = bj, tw[0] = 1.0f, wsum = 1.0f;
        }
        for (const UpsampleImage& im : images) {
          const int cn = im.half.channels();
          float acc[kMaxChannels] = {0.0f, 0.0f, 0.0f, 0.0f};
          for (int t = 0; t < n_taps; ++t) {
            const float* v = im.half.ptr<float>(tj[t]) + size_t(ti[t]) * size_t(cn);
            for (int ch = 0; ch < cn; ++ch) acc[ch] += tw[t] * v[ch];
          }
          float* out = im.full.ptr<float>(y) + size_t(x) * size_t(cn);
          for (int ch = 0; ch < cn; ++ch) out[ch] = acc[ch] / wsum;
        }
      }
    }
  });
}

}  // namespace ssdo
