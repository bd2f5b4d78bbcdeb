#include "kernels/metrics.h"

#include <gtest/gtest.h>

namespace ssdo {
namespace {

TEST(Metrics, KnownErrorsOverMask) {
  // Errors +0.1, -0.3, +0.2 on three masked-in pixels; the fourth pixel is masked out.
  cv::Mat est = (cv::Mat_<float>(1, 4) << 0.6f, 0.2f, 0.9f, 100.0f);
  cv::Mat ref = (cv::Mat_<float>(1, 4) << 0.5f, 0.5f, 0.7f, 0.0f);
  cv::Mat mask = (cv::Mat_<uint8_t>(1, 4) << 255, 255, 255, 0);
  const ErrorStats s = compare_images(est, ref, mask);
  EXPECT_EQ(s.pixels, 3);
  EXPECT_NEAR(s.mae, 0.2, 1e-6);
  EXPECT_NEAR(s.bias, 0.0, 1e-6);
  EXPECT_NEAR(s.rmse, std::sqrt((0.01 + 0.09 + 0.04) / 3.0), 1e-6);
  EXPECT_NEAR(s.max_abs, 0.3, 1e-6);
  EXPECT_NEAR(s.p95, 0.3, 1e-6);
  EXPECT_NEAR(s.mean_reference, (0.5 + 0.5 + 0.7) / 3.0, 1e-6);
}

TEST(Metrics, NonFiniteValuesAreSkipped) {
  cv::Mat est = (cv::Mat_<float>(1, 3) << NAN, 1.0f, INFINITY);
  cv::Mat ref = (cv::Mat_<float>(1, 3) << 0.0f, 0.5f, 0.0f);
  const ErrorStats s = compare_images(est, ref, cv::Mat());
  EXPECT_EQ(s.pixels, 1);
  EXPECT_NEAR(s.mae, 0.5, 1e-6);
}

TEST(Metrics, ColourImagesCompareChannelMeans) {
  cv::Mat est(1, 1, CV_32FC3, cv::Scalar(0.3, 0.6, 0.9));
  cv::Mat ref(1, 1, CV_32FC3, cv::Scalar(0.2, 0.5, 0.8));
  EXPECT_NEAR(compare_images(est, ref, cv::Mat()).bias, 0.1, 1e-6);
}

TEST(Metrics, AccumulatorWeightsByPixels) {
  ErrorAccumulator acc;
  acc.add(cv::Mat(1, 1, CV_32F, cv::Scalar(1.0)), cv::Mat(1, 1, CV_32F, cv::Scalar(0.0)), cv::Mat());
  acc.add(cv::Mat(1, 3, CV_32F, cv::Scalar(0.0)), cv::Mat(1, 3, CV_32F, cv::Scalar(0.0)), cv::Mat());
  const ErrorStats s = acc.result();
  EXPECT_EQ(s.pixels, 4);
  EXPECT_NEAR(s.mae, 0.25, 1e-9);
  EXPECT_NEAR(s.max_abs, 1.0, 1e-9);
}

TEST(Metrics, ErrorPerConfidenceDecile) {
  // Eight pixels, one masked out and one with a NaN confidence: errors 0.1 and 0.3 in
  // [0, 0.1) (confidence 0 and 0.0999), 0.2 in [0.2, 0.3) (0.2999999 stays below 0.3),
  // 0.05 in [0.3, 0.4) (0.3 exactly), 0.4 in the last bin (1 and 1.5: 1 closes it).
  cv::Mat est = (cv::Mat_<float>(1, 8) << 0.6f, 0.2f, 0.9f, 0.55f, 0.9f, 0.1f, 0.0f, 0.3f);
  cv::Mat ref = (cv::Mat_<float>(1, 8) << 0.5f, 0.5f, 0.7f, 0.5f, 0.5f, 0.5f, 0.9f, 0.3f);
  cv::Mat conf = (cv::Mat_<float>(1, 8) << 0.0f, 0.0999f, 0.2999999f, 0.3f, 1.0f, 1.5f, 0.5f, NAN);
  cv::Mat mask = (cv::Mat_<uint8_t>(1, 8) << 255, 255, 255, 255, 255, 255, 0, 255);
  ConfidenceDeciles d;
  d.add(est, ref, conf, mask);
  const int64_t expected_pixels[10] = {2, 0, 1, 1, 0, 0, 0, 0, 0, 2};
  const double expected_mae[10] = {0.2, 0, 0.2, 0.05, 0, 0, 0, 0, 0, 0.4};
  for (int b = 0; b < ConfidenceDeciles::kBins; ++b) {
    EXPECT_EQ(d.pixels(b), expected_pixels[b]) << "bin " << b;
    EXPECT_NEAR(d.mae(b), expected_mae[b], 1e-6) << "bin " << b;
  }
  // Summing two runs weighs by pixels: bin 0 gets a third pixel with error 0.5.
  ConfidenceDeciles other;
  other.add((cv::Mat_<float>(1, 1) << 1.0f), (cv::Mat_<float>(1, 1) << 0.5f), (cv::Mat_<float>(1, 1) << 0.05f),
            cv::Mat());
  d.add(other);
  EXPECT_EQ(d.pixels(0), 3);
  EXPECT_NEAR(d.mae(0), (0.1 + 0.3 + 0.5) / 3.0, 1e-6);
  EXPECT_EQ(ConfidenceDeciles::bin(-0.5f), 0);
  EXPECT_EQ(ConfidenceDeciles::bin(0.9f), 9);
  EXPECT_EQ(ConfidenceDeciles::bin(0.8999999f), 8);
}

}  // namespace
}  // namespace ssdo
