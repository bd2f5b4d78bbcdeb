#include "kernels/denoise.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "kernels/parallel.h"

namespace ssdo {
namespace {

constexpr int kMaxRadiusPx = 32;

template <int C>
void bilateral(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
               const cv::Mat& mask, const DenoiseSettings& s, cv::Mat& dst, const cv::Rect& r,
               int nthreads) {
  using Pixel = cv::Vec<float, C>;
  const int R = s.radius_px;
  const int width = src.cols, height = src.rows;
  // Gaussian spatial weights g(k), k in [-R, R], computed once.
  float g[2 * kMaxRadiusPx + 1];
  for (int k = -R; k <= R; ++k) g[k + R] = std::exp(-0.5f * float(k * k) / (s.sigma_px * s.sigma_px));
  const float power = s.normal_power;
  // Integer powers (the default 16) by repeated squaring: std::pow per tap costs more than
  // the rest of the weight together.
  const bool integer_power = power == std::floor(power);
  const unsigned ipower = integer_power ? unsigned(power) : 0u;
  auto lobe = [&](float c) -> float {
    if (!integer_power) return std::pow(c, power);
    float result = 1.0f, base = c;
    for (unsigned e = ipower; e; e >>= 1) {
      if (e & 1u) result *= base;
      base *= base;
    }
    return result;
  };
  const float inv_tol = 1.0f / s.depth_tolerance_relative;

  // Range weight of a tap against a centre (depth d, normal n): hard-cut linear depth
  // weight times the normal lobe; 0 for masked taps.
  auto range_weight = [&](int tx, int ty, float d, const cv::Vec3f& n) -> float {
    if (!mask.ptr<uint8_t>(ty)[tx]) return 0.0f;
    const float dt = depth_view.ptr<float>(ty)[tx];
    const float wd = 1.0f - std::abs(dt - d) * inv_tol / d;
    if (!(wd > 0.0f)) return 0.0f;
    const float cosn = n.dot(normal_view.ptr<cv::Vec3f>(ty)[tx]);
    if (!(cosn > 0.0f)) return 0.0f;
    return wd * lobe(cosn);
  };

  // Pass 1 (horizontal) over the rows the vertical pass reads, roi columns only.
  const int y0 = std::max(0, r.y - R), y1 = std::min(height, r.y + r.height + R);
  cv::Mat tmp(y1 - y0, r.width, CV_MAKETYPE(CV_32F, C));
  parallel_rows(cv::Range(y0, y1), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const Pixel* in = src.ptr<Pixel>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* dep = depth_view.ptr<float>(y);
      const cv::Vec3f* nor = normal_view.ptr<cv::Vec3f>(y);
      Pixel* out = tmp.ptr<Pixel>(y - y0);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!m[x]) {
          out[x - r.x] = in[x];
          continue;
        }
        const float d = dep[x];
        const cv::Vec3f n = nor[x];
        const int k0 = std::max(-R, -x), k1 = std::min(R, width - 1 - x);
        Pixel sum = Pixel::all(0.0f);
        float wsum = 0.0f;
        for (int k = k0; k <= k1; ++k) {
          const float w = g[k + R] * range_weight(x + k, y, d, n);
          sum += w * in[x + k];
          wsum += w;
        }
        out[x - r.x] = sum * (1.0f / wsum);  // wsum >= g(0) * 1 (the centre) > 0
      }
    }
  });

  // Pass 2 (vertical) over the roi, reading pass 1.
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const Pixel* in = src.ptr<Pixel>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* dep = depth_view.ptr<float>(y);
      const cv::Vec3f* nor = normal_view.ptr<cv::Vec3f>(y);
      Pixel* out = dst.ptr<Pixel>(y);
      const int k0 = std::max(-R, y0 - y), k1 = std::min(R, y1 - 1 - y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!m[x]) {
          out[x] = in[x];
          continue;
        }
        const float d = dep[x];
        const cv::Vec3f n = nor[x];
        Pixel sum = Pixel::all(0.0f);
        float wsum = 0.0f;
        for (int k = k0; k <= k1; ++k) {
          const float w = g[k + R] * range_weight(x, y + k, d, n);
          sum += w * tmp.ptr<Pixel>(y + k - y0)[x - r.x];
          wsum += w;
        }
        out[x] = sum * (1.0f / wsum);
      }
    }
  });
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

std::string validate(const DenoiseSettings& s) {
  auto bad = [](const char* field, double value, const char* range) {
    return std::string(field) + " = " + std::to_string(value) + " is out of range " + range;
  };
  if (s.radius_px < 0 || s.radius_px > kMaxRadiusPx) return bad("radius_px", s.radius_px, "[0, 32]");
  if (!(s.sigma_px > 0.0f) || !std::isfinite(s.sigma_px)) return bad("sigma_px", s.sigma_px, "(0, inf)");
  if (!(s.depth_tolerance_relative > 0.0f) || !std::isfinite(s.depth_tolerance_relative))
    return bad("depth_tolerance_relative", s.depth_tolerance_relative, "(0, inf)");
  if (!(s.normal_power >= 0.0f && s.normal_power <= 256.0f))
    return bad("normal_power", s.normal_power, "[0, 256]");
  return {};
}

void denoise_bilateral(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
                       const cv::Mat& mask, const DenoiseSettings& settings, cv::Mat& dst,
                       cv::Rect roi, int nthreads) {
  CV_Assert(validate(settings).empty());
  CV_Assert(depth_view.type() == CV_32FC1 && depth_view.size() == src.size());
  CV_Assert(normal_view.type() == CV_32FC3 && normal_view.size() == src.size());
  CV_Assert(mask.type() == CV_8UC1 && mask.size() == src.size());
  prepare_dst(src, dst);
  const cv::Rect r = resolve_roi(roi, src.size());
  if (r.empty()) return;
  if (src.channels() == 1)
    bilateral<1>(src, depth_view, normal_view, mask, settings, dst, r, nthreads);
  else
    bilateral<3>(src, depth_view, normal_view, mask, settings, dst, r, nthreads);
}

void box_blur_4x4(const cv::Mat& src, cv::Mat& dst, cv::Rect roi, int nthreads) {
  prepare_dst(src, dst);
  const cv::Rect r = resolve_roi(roi, src.size());
  if (r.empty()) return;
  if (src.channels() == 1)
    box4<1>(src, dst, r, nthreads);
  else
    box4<3>(src, dst, r, nthreads);
}

}  // namespace ssdo
