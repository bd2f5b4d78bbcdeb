#include "kernels/metrics.h"

#include <algorithm>
#include <cmath>

#include "kernels/reprojection.h"

namespace ssdo {

namespace {

// Mean over channels of a pixel of a CV_32FC(n) row.
inline float channel_mean(const float* p, int channels) {
  float s = 0;
  for (int c = 0; c < channels; ++c) s += p[c];
  return s / float(channels);
}

// Calls fn(x, y, estimate, reference) for every compared pixel (mask != 0, both channel
// means finite), in row-major order.
template <typename Fn>
void for_each_compared_pixel(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask, Fn&& fn) {
  CV_Assert(estimate.size() == reference.size() && estimate.type() == reference.type());
  CV_Assert(estimate.depth() == CV_32F);
  CV_Assert(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == estimate.size()));
  const int channels = estimate.channels();
  for (int y = 0; y < estimate.rows; ++y) {
    const float* e = estimate.ptr<float>(y);
    const float* r = reference.ptr<float>(y);
    const uint8_t* m = mask.empty() ? nullptr : mask.ptr<uint8_t>(y);
    for (int x = 0; x < estimate.cols; ++x) {
      if (m && !m[x]) continue;
      const float ev = channel_mean(e + x * channels, channels);
      const float rv = channel_mean(r + x * channels, channels);
      if (std::isfinite(ev) && std::isfinite(rv)) fn(x, y, ev, rv);
    }
  }
}

}  // namespace

void ErrorAccumulator::add(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask) {
  for_each_compared_pixel(estimate, reference, mask, [&](int, int, float ev, float rv) {
    const double d = double(ev) - double(rv);
    abs_errors_.push_back(float(std::abs(d)));
    sum_abs_ += std::abs(d);
    sum_sq_ += d * d;
    sum_signed_ += d;
    sum_reference_ += rv;
    max_abs_ = std::max(max_abs_, std::abs(d));
  });
}

ErrorStats ErrorAccumulator::result() const {
  ErrorStats s;
  s.pixels = int64_t(abs_errors_.size());
  if (s.pixels == 0) return s;
  const double n = double(s.pixels);
  s.mae = sum_abs_ / n;
  s.rmse = std::sqrt(sum_sq_ / n);
  s.bias = sum_signed_ / n;
  s.mean_reference = sum_reference_ / n;
  s.max_abs = max_abs_;
  std::vector<float> sorted = abs_errors_;
  const size_t k = std::min(sorted.size() - 1, size_t(std::ceil(0.95 * n)) - 1);
  std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
  s.p95 = sorted[k];
  return s;
}

int ConfidenceDeciles::bin(float confidence) {
  // The bounds are the floats nearest b/10 (0.9f opens the last bin): c x 10 in float may
  // round across a bound, so the bin is corrected by comparing with its bounds.
  int b = std::clamp(int(std::floor(confidence * float(kBins))), 0, kBins - 1);
  if (b + 1 < kBins && confidence >= float(b + 1) / float(kBins)) ++b;
  if (b > 0 && confidence < float(b) / float(kBins)) --b;
  return b;
}

void ConfidenceDeciles::add(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& confidence,
                            const cv::Mat& mask) {
  CV_Assert(confidence.type() == CV_32FC1 && confidence.size() == estimate.size());
  for_each_compared_pixel(estimate, reference, mask, [&](int x, int y, float ev, float rv) {
    const float c = confidence.ptr<float>(y)[x];
    if (!std::isfinite(c)) return;
    const size_t b = size_t(bin(c));
    ++pixels_[b];
    sum_abs_[b] += std::abs(double(ev) - double(rv));
  });
}

void ConfidenceDeciles::add(const ConfidenceDeciles& other) {
  for (size_t b = 0; b < size_t(kBins); ++b) {
    pixels_[b] += other.pixels_[b];
    sum_abs_[b] += other.sum_abs_[b];
  }
}

double ConfidenceDeciles::mae(int bin) const {
  const size_t b = size_t(bin);
  return pixels_[b] > 0 ? sum_abs_[b] / double(pixels_[b]) : 0.0;
}

ErrorStats compare_images(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask) {
  ErrorAccumulator acc;
  acc.add(estimate, reference, mask);
  return acc.result();
}

void FlickerAccumulator::add(const FlickerFrame& a, const FlickerFrame& b) {
  CV_Assert(a.estimate.type() == b.estimate.type() && a.reference.type() == a.estimate.type() &&
            b.reference.type() == b.estimate.type() && a.estimate.depth() == CV_32F);
  const Reprojection reprojection(a.camera, b.camera);
  const int channels = a.estimate.channels();
  for (int y = 0; y < a.depth_view.rows; ++y) {
    const uint8_t* mask_row = a.mask.ptr<uint8_t>(y);
    for (int x = 0; x < a.depth_view.cols; ++x) {
      if (!mask_row[x]) continue;
      const float depth_view = a.depth_view.ptr<float>(y)[x];
      const float* n = a.normal_view.ptr<float>(y) + 3 * x;
      const Reprojection::Carried p = reprojection.carry(x, y, depth_view, glm::vec3(n[0], n[1], n[2]));
      if (!(p.pixel.x >= 0.0f && p.pixel.y >= 0.0f && p.pixel.x < float(b.depth_view.cols) &&
            p.pixel.y < float(b.depth_view.rows)))
        continue;
      const int qx = int(p.pixel.x), qy = int(p.pixel.y);
      if (!b.mask.ptr<uint8_t>(qy)[qx]) continue;
      const float* nq = b.normal_view.ptr<float>(qy) + 3 * qx;
      if (glm::dot(p.normal_view, glm::vec3(nq[0], nq[1], nq[2])) < settings_.normal_min_cos) continue;
      const float e = reprojection.plane_distance(p, qx, qy, b.depth_view.ptr<float>(qy)[qx]);
      if (!(e <= settings_.depth_tolerance_relative * depth_view)) continue;
      const float reference_change = std::abs(channel_mean(b.reference.ptr<float>(qy) + channels * qx, channels) -
                                              channel_mean(a.reference.ptr<float>(y) + channels * x, channels));
      const float change = std::abs(channel_mean(b.estimate.ptr<float>(qy) + channels * qx, channels) -
                                    channel_mean(a.estimate.ptr<float>(y) + channels * x, channels));
      if (!(reference_change < settings_.reference_change_max) || !std::isfinite(change)) continue;
      ++pixels_;
      sum_change_ += change;
      sum_reference_ += reference_change;
    }
  }
}

}  // namespace ssdo
