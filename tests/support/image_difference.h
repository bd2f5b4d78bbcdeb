// The largest difference between two images of one size, type and channel count, as floats:
// cv::norm has no half-float path (on CV_16F it reads the bits as other types), so images
// stored in half (the bent normal, SSDO's raw terms) are widened first. Exact: every half
// is a float.
#pragma once

#include <limits>

#include <opencv2/core.hpp>

namespace ssdo::test {

inline double max_difference(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return std::numeric_limits<double>::infinity();
  if (a.empty()) return 0.0;
  if (a.depth() != CV_16F) return cv::norm(a, b, cv::NORM_INF);
  cv::Mat wide_a, wide_b;
  a.convertTo(wide_a, CV_32F);
  b.convertTo(wide_b, CV_32F);
  return cv::norm(wide_a, wide_b, cv::NORM_INF);
}

}  // namespace ssdo::test
