// The lower envelope of parabolas (kernels/distance_transform.h) on lines whose distances and
// nearest samples are known exactly.
#include "kernels/distance_transform.h"

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

}  // namespace
}  // namespace ssdo::distance_transform_test
