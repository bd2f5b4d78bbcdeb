// Error statistics of an estimate against a reference image over a mask: what
// `ssdo eval`, the benchmarks and the accuracy tests report.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace ssdo {

struct ErrorStats {
  int64_t pixels = 0;   // pixels compared (mask != 0, both values finite)
  double mae = 0;       // mean |estimate - reference|
  double rmse = 0;      // sqrt(mean (estimate - reference)^2)
  double bias = 0;      // mean (estimate - reference): > 0 = estimate too bright/open
  double p95 = 0;       // 95th percentile of |estimate - reference|
  double max_abs = 0;   // largest |estimate - reference|
  double mean_reference = 0;  // mean of the reference (for relative errors: mae / mean_reference)
};

// Compares single-channel float images (CV_32FC1), or multi-channel ones averaged over
// channels per pixel, over pixels where mask (CV_8UC1) is non-zero; an empty mask
// compares every pixel.
ErrorStats compare_images(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask);

// Accumulates several frames' statistics into one (pixel-weighted; p95 and max over all).
class ErrorAccumulator {
 public:
  void add(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask);
  ErrorStats result() const;

 private:
  std::vector<float> abs_errors_;
  double sum_abs_ = 0, sum_sq_ = 0, sum_signed_ = 0, sum_reference_ = 0, max_abs_ = 0;
};

}  // namespace ssdo
