// Error statistics of an estimate against a reference image over a mask: what
// `ssdo eval`, the benchmarks and the accuracy tests report.
#pragma once

#include <array>
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

// Mean |estimate - reference| of the pixels binned by a per-pixel confidence (the
// `confidence` channel, kernels/confidence.h): bin b holds confidence in [b/10, (b+1)/10)
// (the bounds as floats: 0.9f opens the last bin), the last bin also 1 (values below 0
// count in the first bin, above 1 in the last). Over
// the pixels compare_images compares whose confidence is finite.
class ConfidenceDeciles {
 public:
  static constexpr int kBins = 10;

  // estimate, reference as compare_images; confidence CV_32FC1 of the same size.
  void add(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& confidence, const cv::Mat& mask);
  void add(const ConfidenceDeciles& other);  // pixel-weighted: as if added image by image

  static int bin(float confidence);  // the bin of a finite confidence
  int64_t pixels(int bin) const { return pixels_[size_t(bin)]; }
  double mae(int bin) const;  // 0 for an empty bin

 private:
  std::array<int64_t, kBins> pixels_{};
  std::array<double, kBins> sum_abs_{};
};

}  // namespace ssdo
