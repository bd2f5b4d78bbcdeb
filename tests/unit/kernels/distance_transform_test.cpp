// The lower envelope of parabolas (kernels/distance_transform.h) on lines whose distances and
// nearest samples are known exactly, and the image transform against brute force.
#include "kernels/distance_transform.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace ssdo::distance_transform_test {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Two zeros at 2 and 9 on a line of 12: each sample's squared distance to the nearer, and
// which; a raised root (f = 5 at 6) wins only where it lies under both parabolas.
TEST(DistanceTransform, LowerEnvelopeGivesTheSquaredDistanceAndTheNearestSample) {
  std::vector<float> f(12, kInf), d(12);
  std::vector<int> nearest(12);
  EnvelopeScratch scratch(12);
  f[2] = 0.0f;
  f[9] = 0.0f;
  lower_envelope(f.data(), 12, d.data(), nearest.data(), scratch);
  const float expected[] = {4, 1, 0, 1, 4, 9, 9, 4, 1, 0, 1, 4};
  const int from[] = {2, 2, 2, 2, 2, 2, 9, 9, 9, 9, 9, 9};
  for (int q = 0; q < 12; ++q) {
    EXPECT_EQ(d[size_t(q)], expected[q]) << q;
    EXPECT_EQ(nearest[size_t(q)], from[q]) << q;
  }
  f[6] = 5.0f;  // (q - 6)^2 + 5 lies under both zeros' parabolas at q = 5 and 6 only
  lower_envelope(f.data(), 12, d.data(), nearest.data(), scratch);
  EXPECT_EQ(d[6], 5.0f);
  EXPECT_EQ(nearest[6], 6);
  EXPECT_EQ(d[5], 6.0f);  // (5 - 6)^2 + 5 = 6 < 9
  EXPECT_EQ(nearest[5], 6);
  EXPECT_EQ(d[4], 4.0f);  // the zero at 2 stays nearer
  EXPECT_EQ(nearest[4], 2);
  EXPECT_EQ(d[7], 4.0f);  // and the zero at 9
  EXPECT_EQ(nearest[7], 9);
}

// No finite sample: every distance +inf and no nearest sample; the distances alone without
// the nearest samples' output.
TEST(DistanceTransform, ALineWithoutSamplesIsInfinitelyFar) {
  std::vector<float> f(5, kInf), d(5);
  std::vector<int> nearest(5, 7);
  EnvelopeScratch scratch(5);
  lower_envelope(f.data(), 5, d.data(), nearest.data(), scratch);
  for (int q = 0; q < 5; ++q) {
    EXPECT_EQ(d[size_t(q)], kInf);
    EXPECT_EQ(nearest[size_t(q)], -1);
  }
  f[4] = 0.0f;
  lower_envelope(f.data(), 5, d.data(), nullptr, scratch);
  EXPECT_EQ(d[0], 16.0f);
}

// The image transform against the minimum written out over every mark; the nearest mark it
// gives is a mark at that distance.
TEST(DistanceTransform, SquaredDistanceIsTheNearestMarks) {
  cv::Mat marks = cv::Mat::zeros(37, 53, CV_8UC1);
  cv::RNG rng(5);
  for (int i = 0; i < 12; ++i) marks.at<uint8_t>(rng.uniform(0, marks.rows), rng.uniform(0, marks.cols)) = 255;
  marks(cv::Rect(40, 3, 6, 4)).setTo(255);
  for (const int threads : {1, 3}) {
    cv::Mat nearest;
    const cv::Mat d = squared_distance_to_marks(marks, threads, &nearest);
    ASSERT_EQ(d.type(), CV_32FC1);
    ASSERT_EQ(nearest.type(), CV_32SC2);
    for (int y = 0; y < marks.rows; ++y)
      for (int x = 0; x < marks.cols; ++x) {
        float best = std::numeric_limits<float>::infinity();
        for (int my = 0; my < marks.rows; ++my)
          for (int mx = 0; mx < marks.cols; ++mx)
            if (marks.at<uint8_t>(my, mx)) best = std::min(best, float((x - mx) * (x - mx) + (y - my) * (y - my)));
        ASSERT_EQ(d.at<float>(y, x), best) << x << "," << y;
        const cv::Point p = nearest.at<cv::Point>(y, x);
        ASSERT_NE(marks.at<uint8_t>(p), 0) << x << "," << y;
        ASSERT_EQ(float((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y)), best) << x << "," << y;
      }
    EXPECT_EQ(cv::norm(d, squared_distance_to_marks(marks, threads), cv::NORM_INF), 0.0);
  }
}

// rows_done sees each row once, its nearest marks already final.
TEST(DistanceTransform, RowsDoneSeesEachFinishedRowOnce) {
  cv::Mat marks = cv::Mat::zeros(29, 41, CV_8UC1);
  marks.at<uint8_t>(3, 5) = marks.at<uint8_t>(20, 33) = 255;
  for (const int threads : {1, 3}) {
    cv::Mat nearest;
    std::vector<cv::Mat> seen(size_t(marks.rows));  // each row written by one call only
    const cv::Mat d = squared_distance_to_marks(marks, threads, &nearest, [&](const cv::Range& rows) {
      for (int y = rows.start; y < rows.end; ++y) {
        ASSERT_TRUE(seen[size_t(y)].empty()) << y;
        seen[size_t(y)] = nearest.row(y).clone();
      }
    });
    for (int y = 0; y < marks.rows; ++y) {
      ASSERT_FALSE(seen[size_t(y)].empty()) << y;
      EXPECT_EQ(cv::norm(seen[size_t(y)], nearest.row(y), cv::NORM_INF), 0.0) << y;
    }
    EXPECT_EQ(nearest.at<cv::Point>(0, 0), cv::Point(5, 3));
    EXPECT_EQ(d.at<float>(0, 0), 34.0f);
  }
}

// Two marks of a column equally near a pixel between them: the one above, as the lower
// envelope takes the earlier of two samples at a tie (the thickness estimate's bits depend
// on which). The columns beside them take the same rows.
TEST(DistanceTransform, OfTwoMarksEquallyNearInAColumnTheOneAbove) {
  cv::Mat marks = cv::Mat::zeros(9, 5, CV_8UC1);
  marks.at<uint8_t>(1, 2) = marks.at<uint8_t>(5, 2) = 255;
  for (const int threads : {1, 2}) {
    cv::Mat nearest;
    const cv::Mat d = squared_distance_to_marks(marks, threads, &nearest);
    EXPECT_EQ(nearest.at<cv::Point>(3, 2), cv::Point(2, 1));
    EXPECT_EQ(d.at<float>(3, 2), 4.0f);
    EXPECT_EQ(nearest.at<cv::Point>(3, 0), cv::Point(2, 1));
    EXPECT_EQ(d.at<float>(3, 0), 8.0f);
    EXPECT_EQ(nearest.at<cv::Point>(4, 2), cv::Point(2, 5));
    EXPECT_EQ(nearest.at<cv::Point>(8, 4), cv::Point(2, 5));
    EXPECT_EQ(d.at<float>(8, 4), 13.0f);
  }
}

TEST(DistanceTransform, NoMarkIsInfinitelyFar) {
  cv::Mat nearest;
  const cv::Mat d = squared_distance_to_marks(cv::Mat::zeros(8, 9, CV_8UC1), 0, &nearest);
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x) {
      EXPECT_TRUE(std::isinf(d.at<float>(y, x)));
      EXPECT_EQ(nearest.at<cv::Point>(y, x), cv::Point(-1, -1));
    }
}

}  // namespace
}  // namespace ssdo::distance_transform_test
