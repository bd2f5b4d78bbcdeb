#include "kernels/temporal.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/temporal.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>

#include "core/parallel.h"
#include "kernels/integer_power.h"
#include "kernels/reprojection.h"
#include "kernels/settings_check.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

// Every term's channels of one pixel, summed at once (AO + two RGB SSDO terms = 7).
constexpr int kMaxChannels = 16;
using Channels = std::array<float, kMaxChannels>;
// Whether a neighbour is used is measured on every 4th pixel of every 4th row.
constexpr int kMeasureStridePx = 4;

struct Neighbour {
  const TemporalFrame* frame;
  Reprojection reprojection;
};

// max(0, c)^power for c in (0, 1]: integer powers (the default 16) by squaring, the rest
// with std::pow.
inline float normal_lobe(float c, float power) {
  const unsigned n = unsigned(power);
  return float(n) == power ? integer_power(c, n, 1.0f) : std::pow(c, power);
}

inline glm::vec3 normal_at(const cv::Mat& normal_view, int x, int y) {
  const float* n = normal_view.ptr<float>(y) + 3 * x;
  return {n[0], n[1], n[2]};
}

// The weight of texel (tx, ty) of a neighbour for the carried point p of a pixel at planar
// depth depth_view (temporal.h), without the bilinear factor; 0 outside the image, on
// background or on another surface. inverse_tolerance = 1 / (depth_tolerance_relative x
// depth_view), the pixel's.
inline float texel_weight(const Neighbour& n, const Reprojection::Carried& p, float inverse_tolerance, int tx, int ty,
                          const TemporalSettings& s) {
  const TemporalFrame& u = *n.frame;
  if (tx < 0 || ty < 0 || tx >= u.depth_view.cols || ty >= u.depth_view.rows || !u.mask.ptr<uint8_t>(ty)[tx])
    return 0.0f;
  const float e = Reprojection::plane_distance(p, tx, ty, u.depth_view.ptr<float>(ty)[tx]);
  const float w_plane = 1.0f - e * inverse_tolerance;
  if (!(w_plane > 0.0f)) return 0.0f;
  const float c = glm::dot(p.normal_view, normal_at(u.normal_view, tx, ty));
  if (!(c > 0.0f)) return 0.0f;
  return w_plane * normal_lobe(c, s.normal_power);
}

// Adds w x the texel's channels (every term in order) to sum.
void add_texel(const TemporalFrame& u, int tx, int ty, float w, Channels& sum) {
  int k = 0;
  for (const cv::Mat* term : u.terms) {
    const float* v = term->ptr<float>(ty) + term->channels() * tx;
    for (int c = 0; c < term->channels(); ++c) sum[size_t(k++)] += w * v[c];
  }
}

// The neighbours' bilinear taps around each one's projection of pixel (x, y): their
// weighted channels added to sum, and the total weight.
float neighbour_taps(std::span<const Neighbour> neighbours, const TemporalFrame& f, int x, int y,
                     const TemporalSettings& s, Channels& sum) {
  const float depth_view = f.depth_view.ptr<float>(y)[x];
  const float inverse_tolerance = 1.0f / (s.depth_tolerance_relative * depth_view);
  const glm::vec3 normal = normal_at(f.normal_view, x, y);
  float total = 0.0f;
  for (const Neighbour& n : neighbours) {
    const Reprojection::Carried p = n.reprojection.carry(x, y, depth_view, normal);
    if (!(std::isfinite(p.pixel.x) && std::isfinite(p.pixel.y))) continue;
    // Texel centres around the point: floor(pixel - 0.5) and the next one, in x and y.
    const float gx = p.pixel.x - 0.5f, gy = p.pixel.y - 0.5f;
    const float fx = std::floor(gx), fy = std::floor(gy);
    if (!(fx >= -1.0f && fy >= -1.0f && fx < float(n.frame->depth_view.cols) && fy < float(n.frame->depth_view.rows)))
      continue;
    const float ax = gx - fx, ay = gy - fy;
    const int x0 = int(fx), y0 = int(fy);
    const float bilinear[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
    for (int i = 0; i < 4; ++i) {
      const int tx = x0 + (i & 1), ty = y0 + (i >> 1);
      if (!(bilinear[i] > 0.0f)) continue;
      const float w = bilinear[i] * texel_weight(n, p, inverse_tolerance, tx, ty, s);
      if (!(w > 0.0f)) continue;
      add_texel(*n.frame, tx, ty, w, sum);
      total += w;
    }
  }
  return total;
}

// One row of the roi: each pixel's terms filtered (temporal.h), or copied where nothing agrees.
void filter_row(const TemporalFrame& f, std::span<const Neighbour> neighbours, const TemporalSettings& s,
                std::span<cv::Mat* const> dsts, int y, int x_begin, int x_end) {
  const uint8_t* mask_row = f.mask.ptr<uint8_t>(y);
  for (int x = x_begin; x < x_end; ++x) {
    Channels sum{};
    const float total = mask_row[x] ? neighbour_taps(neighbours, f, x, y, s, sum) : 0.0f;
    int k = 0;
    for (size_t i = 0; i < f.terms.size(); ++i) {
      const int channels = f.terms[i]->channels();
      const float* src = f.terms[i]->ptr<float>(y) + channels * x;
      float* dst = dsts[i]->ptr<float>(y) + channels * x;
      for (int c = 0; c < channels; ++c, ++k) dst[c] = total > 0.0f ? (src[c] + sum[size_t(k)]) / (1.0f + total) : src[c];
    }
  }
}

// Per neighbour, over every kMeasureStridePx-th pixel of every kMeasureStridePx-th row of
// the frame's foreground: the points that project into it and those whose nearest texel
// holds another surface (background, or the plane or normal test fails). Integer counts:
// the same for any split of the rows.
void measure_neighbour(const TemporalFrame& f, const Neighbour& n, const TemporalSettings& s, TemporalUse& use,
                       int nthreads) {
  std::atomic<int64_t> foreground{0}, seen{0}, disagree{0};
  const cv::Mat& depth_u = n.frame->depth_view;
  const int measured_rows = (f.depth_view.rows + kMeasureStridePx - 1) / kMeasureStridePx;
  parallel_rows(cv::Range(0, measured_rows), nthreads, [&](const cv::Range& rows) {
    int64_t strip_foreground = 0, strip_seen = 0, strip_disagree = 0;
    for (int y = rows.start * kMeasureStridePx; y < rows.end * kMeasureStridePx && y < f.depth_view.rows;
         y += kMeasureStridePx) {
      const float* depth_row = f.depth_view.ptr<float>(y);
      const uint8_t* mask_row = f.mask.ptr<uint8_t>(y);
      for (int x = 0; x < f.depth_view.cols; x += kMeasureStridePx) {
        if (!mask_row[x]) continue;
        ++strip_foreground;
        const Reprojection::Carried p = n.reprojection.carry(x, y, depth_row[x], normal_at(f.normal_view, x, y));
        if (!(p.pixel.x >= 0.0f && p.pixel.y >= 0.0f && p.pixel.x < float(depth_u.cols) &&
              p.pixel.y < float(depth_u.rows)))
          continue;
        ++strip_seen;
        const float inverse_tolerance = 1.0f / (s.depth_tolerance_relative * depth_row[x]);
        strip_disagree += texel_weight(n, p, inverse_tolerance, int(p.pixel.x), int(p.pixel.y), s) <= 0.0f;
      }
    }
    foreground += strip_foreground, seen += strip_seen, disagree += strip_disagree;
  });
  use.overlap = foreground > 0 ? float(double(seen) / double(foreground)) : 0.0f;
  use.disagreement = seen > 0 ? float(double(disagree) / double(seen)) : 0.0f;
  use.used = seen > 0 && use.disagreement <= s.max_disagreement;
}

bool same_layout(const TemporalFrame& f, const TemporalFrame& u) {
  if (u.terms.size() != f.terms.size() || u.depth_view.size() != u.mask.size() ||
      u.normal_view.size() != u.depth_view.size())
    return false;
  for (size_t i = 0; i < f.terms.size(); ++i)
    if (u.terms[i]->type() != f.terms[i]->type() || u.terms[i]->size() != u.depth_view.size()) return false;
  return true;
}

}  // namespace

std::string validate(const TemporalSettings& s) {
  if (!(s.depth_tolerance_relative > 0.0f && s.depth_tolerance_relative <= 1.0f))
    return detail::out_of_range("depth_tolerance_relative", s.depth_tolerance_relative, "(0, 1]");
  if (!(s.normal_power >= 0.0f && s.normal_power <= 256.0f))
    return detail::out_of_range("normal_power", s.normal_power, "[0, 256]");
  if (!(s.max_disagreement >= 0.0f && s.max_disagreement <= 1.0f))
    return detail::out_of_range("max_disagreement", s.max_disagreement, "[0, 1]");
  return {};
}

std::vector<TemporalUse> filter_temporal(const TemporalFrame& frame, std::span<const TemporalFrame> neighbours,
                                         const TemporalSettings& settings, std::span<cv::Mat* const> dsts,
                                         cv::Rect roi, int nthreads) {
  CV_Assert(ssdo::validate(settings).empty());
  CV_Assert(dsts.size() == frame.terms.size());
  int channels = 0;
  for (size_t i = 0; i < frame.terms.size(); ++i) {
    const cv::Mat& src = *frame.terms[i];
    CV_Assert(src.depth() == CV_32F && src.size() == frame.depth_view.size());
    CV_Assert(dsts[i]->data == nullptr || dsts[i]->data != src.data);
    dsts[i]->create(src.size(), src.type());
    channels += src.channels();
  }
  CV_Assert(channels <= kMaxChannels);
  std::vector<TemporalUse> uses(neighbours.size());
  std::vector<Neighbour> used;
  for (size_t i = 0; i < neighbours.size(); ++i) {
    CV_Assert(same_layout(frame, neighbours[i]));
    const Neighbour n{&neighbours[i], Reprojection(frame.camera, neighbours[i].camera)};
    measure_neighbour(frame, n, settings, uses[i], nthreads);
    if (uses[i].used) used.push_back(n);
  }
  const cv::Rect r = resolve_roi(roi, frame.depth_view.size());
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) filter_row(frame, used, settings, dsts, y, r.x, r.x + r.width);
  });
  return uses;
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

// Not per pixel: the baseline's code serves every CPU.
std::string validate(const TemporalSettings& s) { return HWY_NAMESPACE::validate(s); }

HWY_EXPORT(filter_temporal);
std::vector<TemporalUse> filter_temporal(const TemporalFrame& frame, std::span<const TemporalFrame> neighbours,
                                         const TemporalSettings& settings, std::span<cv::Mat* const> dsts, cv::Rect roi,
                                         int nthreads) {
  return HWY_DYNAMIC_DISPATCH(filter_temporal)(frame, neighbours, settings, dsts, roi, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
