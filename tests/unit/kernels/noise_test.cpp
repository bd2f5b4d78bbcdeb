// Deterministic noise helpers (kernels/noise.h).
#include "kernels/noise.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

// The per-pixel rotation: within 1e-7 of cos and sin of 2 pi t for the noise values
// (multiples of 2^-24 in [0, 1)) and beyond them, exact at the quarter turns.
TEST(Noise, SincosTurnsIsWithinATenthOfAMillionth) {
  double worst = 0.0;
  for (uint32_t i = 0; i < (1u << 24); i += 97) {
    const float t = float(i) * (1.0f / 16777216.0f);
    float c = 0.0f, s = 0.0f;
    sincos_turns(t, c, s);
    const double a = 2.0 * 3.14159265358979323846 * double(t);
    worst = std::max({worst, std::abs(double(c) - std::cos(a)), std::abs(double(s) - std::sin(a))});
  }
  EXPECT_LT(worst, 1e-7);
  EXPECT_GT(worst, 0.0);  // not the library's values by another name
  for (const float t : {-1.3f, 2.7f, 17.125f}) {
    float c = 0.0f, s = 0.0f;
    sincos_turns(t, c, s);
    EXPECT_NEAR(c, std::cos(2.0 * 3.14159265358979323846 * double(t)), 1e-6) << t;
    EXPECT_NEAR(s, std::sin(2.0 * 3.14159265358979323846 * double(t)), 1e-6) << t;
  }
  const float quarters[4][2] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}};
  for (int q = 0; q < 4; ++q) {
    float c = 0.0f, s = 0.0f;
    sincos_turns(0.25f * float(q), c, s);
    EXPECT_EQ(c, quarters[q][0]) << q;
    EXPECT_EQ(s, quarters[q][1]) << q;
  }
}

}  // namespace
}  // namespace ssdo
