// Deterministic noise: a pure function of (pixel, sample index, seed), so a kernel's
// output is identical for any thread count and any strip split.
#pragma once

#include <cmath>
#include <cstdint>

namespace ssdo {

// PCG-style integer hash (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient
// Statistically Good Algorithms for Random Number Generation"; the RXS-M-XS output).
constexpr uint32_t hash_u32(uint32_t v) {
  uint32_t state = v * 747796405u + 2891336453u;
  uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

constexpr uint32_t hash_pixel(int x_px, int y_px, uint32_t index, uint32_t seed) {
  return hash_u32(hash_u32(hash_u32(uint32_t(x_px) ^ (seed * 0x9E3779B9u)) + uint32_t(y_px)) + index);
}

// Uniform float in [0, 1) from the top 24 bits of a hash.
constexpr float unit_float(uint32_t h) { return float(h >> 8) * (1.0f / 16777216.0f); }

constexpr float noise01(int x_px, int y_px, uint32_t index, uint32_t seed) {
  return unit_float(hash_pixel(x_px, y_px, index, seed));
}

// The R2 low-discrepancy sequence (Roberts 2018, "The Unreasonable Effectiveness of
// Quasirandom Sequences"): point n in [0,1)^2, offset by `shift` (e.g. per-pixel noise).
inline void r2_point(uint32_t n, float shift_x, float shift_y, float& u, float& v) {
  constexpr double a1 = 0.7548776662466927;  // 1 / plastic number
  constexpr double a2 = 0.5698402909980532;  // 1 / plastic number^2
  double x = shift_x + a1 * double(n), y = shift_y + a2 * double(n);
  u = float(x - static_cast<double>(static_cast<int64_t>(x)));
  v = float(y - static_cast<double>(static_cast<int64_t>(y)));
}

// cos(2 pi t) and sin(2 pi t): a per-pixel rotation from a noise value t (any float of
// moderate size; noise01's in [0, 1)). Within 1e-7 of the exact values (measured at every
// noise01 value), a quarter of the library's sincos time: the nearest quarter turn is
// taken out, and the rest, within pi/4 of it, goes through the Taylor series to x^9 and
// x^10 (truncation < 3e-9).
inline void sincos_turns(float t, float& cos_out, float& sin_out) {
  const float quarter = std::nearbyint(4.0f * t);
  const float x = (4.0f * t - quarter) * 1.57079632679489662f;  // [-pi/4, pi/4]
  const float x2 = x * x;
  const float s = x * (1.0f + x2 * (-1.0f / 6.0f + x2 * (1.0f / 120.0f + x2 * (-1.0f / 5040.0f + x2 * (1.0f / 362880.0f)))));
  const float c = 1.0f + x2 * (-0.5f + x2 * (1.0f / 24.0f + x2 * (-1.0f / 720.0f +
                                                                 x2 * (1.0f / 40320.0f + x2 * (-1.0f / 3628800.0f)))));
  // Rotated by the quarter turns taken out (selects, not a switch: callers run it in
  // vector lanes).
  const int q = int(quarter) & 3;
  cos_out = q == 0 ? c : q == 1 ? -s : q == 2 ? -c : s;
  sin_out = q == 0 ? s : q == 1 ? c : q == 2 ? -s : -c;
}

}  // namespace ssdo
