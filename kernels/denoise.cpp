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

// The single-channel bilateral above, restructured to vectorise (same weights, same
// per-pixel summation order, so the same values): the guides as planes (depth, normal x,
// y, z, with the normal zeroed where mask is 0 so that the lobe weighs masked taps 0, and
// the source zeroed there so that no masked value is ever read into a sum), and each pass
// as an outer loop over the tap offset k and an inner, branch-free loop over a block of
// pixels held on the stack. Integer normal powers only (the lobe by squaring).
// c^P by squaring, unrolled at compile time so the pixel loop stays branch-free.
template <unsigned P>
inline float ipow(float c) {
  if constexpr (P == 0) {
    return 1.0f;
  } else if constexpr (P == 1) {
    return c;
  } else {
    const float h = ipow<P / 2>(c);
    if constexpr (P % 2 == 0) return h * h;
    else return h * h * c;
  }
}

template <class Lobe>
void bilateral_planar(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
                      const cv::Mat& mask, const DenoiseSettings& s, cv::Mat& dst,
                      const cv::Rect& r, int nthreads, Lobe lobe_of) {
  const int R = s.radius_px;
  const int width = src.cols, height = src.rows;
  float g[2 * kMaxRadiusPx + 1];
  for (int k = -R; k <= R; ++k) g[k + R] = std::exp(-0.5f * float(k * k) / (s.sigma_px * s.sigma_px));
  const float inv_tol = 1.0f / s.depth_tolerance_relative;
  // Guide planes over the rows both passes read, all columns (the horizontal pass reads
  // R columns either side of the roi).
  const int y0 = std::max(0, r.y - R), y1 = std::min(height, r.y + r.height + R);
  const int rows = y1 - y0;
  cv::Mat nx(rows, width, CV_32FC1), ny(rows, width, CV_32FC1), nz(rows, width, CV_32FC1);
  cv::Mat value(rows, width, CV_32FC1), tmp(rows, width, CV_32FC1);
  parallel_rows(cv::Range(y0, y1), nthreads, [&](const cv::Range& rr) {
    for (int y = rr.start; y < rr.end; ++y) {
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const cv::Vec3f* n = normal_view.ptr<cv::Vec3f>(y);
      const float* v = src.ptr<float>(y);
      float* px = nx.ptr<float>(y - y0);
      float* py = ny.ptr<float>(y - y0);
      float* pz = nz.ptr<float>(y - y0);
      float* pv = value.ptr<float>(y - y0);
      for (int x = 0; x < width; ++x) {
        const bool on = m[x] != 0;
        px[x] = on ? n[x][0] : 0.0f;
        py[x] = on ? n[x][1] : 0.0f;
        pz[x] = on ? n[x][2] : 0.0f;
        pv[x] = on ? v[x] : 0.0f;
      }
    }
  });

  constexpr int kBlock = 64;
  // One pass: out[x] = sum_k w_k tap_k / sum_k w_k over the taps (xk, yk) = (x + k dx,
  // y + k dy) inside the image, for the block [xa, xb) of row y (plane row py).
  auto pass = [&](int y, int xa, int xb, int dx, int dy, const cv::Mat& taps, float* out) {
    const int pr = y - y0;
    const float* cd = depth_view.ptr<float>(y);
    const float* cx = nx.ptr<float>(pr);
    const float* cy = ny.ptr<float>(pr);
    const float* cz = nz.ptr<float>(pr);
    float sum[kBlock], wsum[kBlock], scale[kBlock];
    for (int x = xa; x < xb; ++x) {
      sum[x - xa] = 0.0f;
      wsum[x - xa] = 0.0f;
      scale[x - xa] = inv_tol / cd[x];
    }
    for (int k = -R; k <= R; ++k) {
      const int ty = y + k * dy;
      if (ty < y0 || ty >= y1) continue;
      // Columns whose tap x + k dx is inside the image.
      const int xs = std::max(xa, -k * dx), xe = std::min(xb, width - k * dx);
      const int tr = ty - y0, off = k * dx;
      const float* td = depth_view.ptr<float>(ty) + off;
      const float* tx = nx.ptr<float>(tr) + off;
      const float* tyn = ny.ptr<float>(tr) + off;
      const float* tz = nz.ptr<float>(tr) + off;
      const float* tv = taps.ptr<float>(tr) + off;
      const float gk = g[k + R];
      for (int x = xs; x < xe; ++x) {
        const int i = x - xa;
        const float wd = std::max(0.0f, 1.0f - std::abs(td[x] - cd[x]) * scale[i]);
        const float c = std::max(0.0f, cx[x] * tx[x] + cy[x] * tyn[x] + cz[x] * tz[x]);
        const float w = gk * (wd * lobe_of(c));
        sum[i] += w * tv[x];
        wsum[i] += w;
      }
    }
    for (int x = xa; x < xb; ++x) out[x] = sum[x - xa] * (1.0f / wsum[x - xa]);
  };

  // Pass 1 (horizontal) over the rows pass 2 reads, roi columns; masked pixels 0 (never read).
  parallel_rows(cv::Range(y0, y1), nthreads, [&](const cv::Range& rr) {
    for (int y = rr.start; y < rr.end; ++y) {
      const uint8_t* m = mask.ptr<uint8_t>(y);
      float* out = tmp.ptr<float>(y - y0);
      for (int xa = r.x; xa < r.x + r.width; xa += kBlock) {
        const int xb = std::min(xa + kBlock, r.x + r.width);
        pass(y, xa, xb, 1, 0, value, out);
        for (int x = xa; x < xb; ++x)
          if (!m[x]) out[x] = 0.0f;
      }
    }
  });
  // Pass 2 (vertical) over the roi; masked pixels copy the source.
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rr) {
    for (int y = rr.start; y < rr.end; ++y) {
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* in = src.ptr<float>(y);
      float* out = dst.ptr<float>(y);
      for (int xa = r.x; xa < r.x + r.width; xa += kBlock) {
        const int xb = std::min(xa + kBlock, r.x + r.width);
        pass(y, xa, xb, 0, 1, tmp, out);
        for (int x = xa; x < xb; ++x)
          if (!m[x]) out[x] = in[x];
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
  auto planar = [&](auto lobe) {
    bilateral_planar(src, depth_view, normal_view, mask, settings, dst, r, nthreads, lobe);
  };
  const float p = settings.normal_power;
  if (src.channels() == 1 && p == 16.0f)
    planar([](float c) { return ipow<16>(c); });
  else if (src.channels() == 1 && p == 8.0f)
    planar([](float c) { return ipow<8>(c); });
  else if (src.channels() == 1 && p == 4.0f)
    planar([](float c) { return ipow<4>(c); });
  else if (src.channels() == 1 && p == 1.0f)
    planar([](float c) { return c; });
  else if (src.channels() == 1 && p == 0.0f)
    planar([](float c) { return c > 0.0f ? 1.0f : 0.0f; });
  else if (src.channels() == 1)
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
