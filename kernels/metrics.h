// Error statistics of an estimate against a reference image over a mask: what
// `ssdo eval`, the benchmarks and the accuracy tests report.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"

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

// ---- Flicker: the reprojected frame-to-frame change of an estimate ----
// A surface point seen in two frames of a shot whose true value barely changes between them
// should get the same estimate in both. The flicker of an estimate over a pair of frames is
// the mean |estimate_b(q) - estimate_a(p)| over the foreground pixels p of frame a whose
// surface is the same at the nearest texel q of their projection into frame b (the plane
// and normal tests of kernels/reprojection.h) and whose reference changes by less than
// reference_change_max there (channel means, as compare_images). The reference's own
// flicker (its Monte-Carlo noise) is the floor an estimate can reach.
struct FlickerSettings {
  // Tangent-plane tolerance relative to p's depth (kernels/reprojection.h), (0, 1]: the
  // temporal filter's (kernels/temporal.h).
  float depth_tolerance_relative = 0.01f;
  // Least cosine between the two normals, [-1, 1]: 0.9 = 26 degrees.
  float normal_min_cos = 0.9f;
  // Pixels whose reference changes by this much or more are not counted (AO units).
  float reference_change_max = 0.05f;
};

// One frame of the pair: estimate and reference CV_32FC1 or CV_32FC3 (the same type),
// geometry in the kernels' conventions (core/gbuffer.h), all of the camera's size.
struct FlickerFrame {
  const cv::Mat& estimate;
  const cv::Mat& reference;
  const cv::Mat& depth_view;   // CV_32FC1 planar, +inf on background
  const cv::Mat& normal_view;  // CV_32FC3 unit view-space normals
  const cv::Mat& mask;         // CV_8UC1, 255 = foreground
  const Camera& camera;
};

// Accumulates the flicker of several pairs of frames (pixel-weighted).
class FlickerAccumulator {
 public:
  explicit FlickerAccumulator(const FlickerSettings& settings = {}) : settings_(settings) {}
  // From the pixels of a into b (call again with b, a for both directions).
  void add(const FlickerFrame& a, const FlickerFrame& b);
  int64_t pixels() const { return pixels_; }
  double mean_change() const { return pixels_ > 0 ? sum_change_ / double(pixels_) : 0.0; }       // of the estimate
  double reference_change() const { return pixels_ > 0 ? sum_reference_ / double(pixels_) : 0.0; }  // its floor

 private:
  FlickerSettings settings_;
  int64_t pixels_ = 0;
  double sum_change_ = 0, sum_reference_ = 0;
};

}  // namespace ssdo
