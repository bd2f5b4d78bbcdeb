#include "kernels/metrics.h"

#include <algorithm>
#include <cmath>

namespace ssdo {

namespace {

// Mean over channels of a pixel of a CV_32FC(n) row.
inline float channel_mean(const float* p, int channels) {
  float s = 0;
  for (int c = 0; c < channels; ++c) s += p[c];
  return s / float(channels);
}

}  // namespace

void ErrorAccumulator::add(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask) {
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
      if (!std::isfinite(ev) || !std::isfinite(rv)) continue;
      const double d = double(ev) - double(rv);
      abs_errors_.push_back(float(std::abs(d)));
      sum_abs_ += std::abs(d);
      sum_sq_ += d * d;
      sum_signed_ += d;
      sum_reference_ += rv;
      max_abs_ = std::max(max_abs_, std::abs(d));
    }
  }
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

ErrorStats compare_images(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask) {
  ErrorAccumulator acc;
  acc.add(estimate, reference, mask);
  return acc.result();
}

}  // namespace ssdo
