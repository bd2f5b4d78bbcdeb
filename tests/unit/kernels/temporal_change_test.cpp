#include "kernels/temporal_change.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

// The distance transform against the minimum written out over every mark.
TEST(TemporalChange, SquaredDistanceIsTheNearestMarks) {
  cv::Mat marks = cv::Mat::zeros(37, 53, CV_8UC1);
  cv::RNG rng(5);
  for (int i = 0; i < 12; ++i) marks.at<uint8_t>(rng.uniform(0, marks.rows), rng.uniform(0, marks.cols)) = 255;
  marks(cv::Rect(40, 3, 6, 4)).setTo(255);
  for (const int threads : {1, 3}) {
    const cv::Mat d = squared_distance_to_marks(marks, threads);
    ASSERT_EQ(d.type(), CV_32FC1);
    for (int y = 0; y < marks.rows; ++y)
      for (int x = 0; x < marks.cols; ++x) {
        float best = std::numeric_limits<float>::infinity();
        for (int my = 0; my < marks.rows; ++my)
          for (int mx = 0; mx < marks.cols; ++mx)
            if (marks.at<uint8_t>(my, mx)) best = std::min(best, float((x - mx) * (x - mx) + (y - my) * (y - my)));
        ASSERT_EQ(d.at<float>(y, x), best) << x << "," << y;
      }
  }
}

TEST(TemporalChange, NoMarkIsInfinitelyFar) {
  const cv::Mat d = squared_distance_to_marks(cv::Mat::zeros(8, 9, CV_8UC1));
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x) EXPECT_TRUE(std::isinf(d.at<float>(y, x)));
}

}  // namespace
}  // namespace ssdo
