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
// Quasirandom Sequences"): point n is frac(n (kR2First, kR2Second)).
inline constexpr double kR2First = 0.7548776662466927;   // 1 / plastic number
inline constexpr double kR2Second = 0.5698402909980532;  // 1 / plastic number^2

// R2's point n in [0,1)^2, offset by `shift` (e.g. per-pixel noise).
inline void r2_point(uint32_t n, float shift_x, float shift_y, float& u, float& v) {
  double x = shift_x + kR2First * double(n), y = shift_y + kR2Second * double(n);
  u = float(x - static_cast<double>(static_cast<int64_t>(x)));
  v = float(y - static_cast<double>(static_cast<int64_t>(y)));
}

// Index of pixel (x, y) along a Hilbert curve over the 64 x 64 tile it lies in (the tiles
// repeat): consecutive indices are neighbouring pixels, and any run of indices covers a
// compact patch (Hilbert 1891; the iterative form of "xy2d", one quadrant bit pair per
// level, the quadrant rotated by selects).
constexpr uint32_t hilbert_index_64(int x_px, int y_px) {
  uint32_t x = uint32_t(x_px) & 63u, y = uint32_t(y_px) & 63u, d = 0;
  for (uint32_t s = 32; s > 0; s >>= 1) {
    const uint32_t rx = (x & s) != 0, ry = (y & s) != 0;
    d += s * s * ((3u * rx) ^ ry);
    const uint32_t flip = (ry == 0 && rx == 1) ? 63u : 0u;
    x ^= flip, y ^= flip;
    const uint32_t tx = ry ? x : y, ty = ry ? y : x;
    x = tx, y = ty;
  }
  return d;
}

// The Hilbert indices of the 64 x 64 tile, each row stored twice over (entry x for x mod 64,
// x in [0, 128)), so that the indices of up to 64 consecutive pixels of a row are
// consecutive entries: a row's loop loads them, and vectorises.
struct HilbertTile {
  uint16_t index[64][128];
};

inline const HilbertTile& hilbert_tile() {
  static const HilbertTile tile = [] {
    HilbertTile t{};
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 128; ++x) t.index[y][x] = uint16_t(hilbert_index_64(x, y));
    return t;
  }();
  return tile;
}

// Spatially stratified noise, two values in [0, 1) per pixel: the R2 sequence (r2_point)
// at the pixel's Hilbert index, shifted per seed (the scheme of XeGTAO's spatial noise).
// Neighbouring pixels take points far apart in the sequence's well-spread order, so any
// compact patch of pixels covers [0, 1)^2 nearly evenly: a blur over the patch averages
// its pixels' estimates as a stratified sample, where white noise (noise01) would leave
// clumps and gaps. A pixel that takes S points of the sequence takes those from index n S
// on (n its Hilbert index), so that neighbours' runs do not overlap. Fixed-point
// arithmetic: the sequence's fractional parts modulo 2^32.
struct StratifiedNoise {
  // R2's generators in units of 2^-32, rounded.
  static constexpr uint32_t kStepU = uint32_t(kR2First * 4294967296.0 + 0.5);
  static constexpr uint32_t kStepV = uint32_t(kR2Second * 4294967296.0 + 0.5);
  uint32_t shift_u = 0, shift_v = 0;  // the seed's offsets, 2^-32 units

  StratifiedNoise() = default;  // no offsets: for constants that assign theirs after (ssdo.cpp)
  explicit StratifiedNoise(uint32_t seed) : shift_u(hash_u32(seed * 2u + 1u)), shift_v(hash_u32(seed * 2u + 2u)) {}
  float u(uint32_t hilbert_index) const { return unit_float(hilbert_index * kStepU + shift_u); }
  float v(uint32_t hilbert_index) const { return unit_float(hilbert_index * kStepV + shift_v); }
  // The two values of pixel (x_px, y_px) alone.
  void at(int x_px, int y_px, float& u_out, float& v_out) const {
    const uint32_t n = index(x_px, y_px);
    u_out = u(n);
    v_out = v(n);
  }

  // The Hilbert indices of pixels x_px .. x_px + 63 of row y_px (frame pixels, any sign).
  static const uint16_t* row_indices(int x_px, int y_px) {
    return hilbert_tile().index[uint32_t(y_px) & 63u] + (uint32_t(x_px) & 63u);
  }
  // hilbert_index_64(x_px, y_px), read from the tile: a per-pixel loop's lookup instead of
  // the curve's six rounds.
  static uint32_t index(int x_px, int y_px) { return *row_indices(x_px, y_px); }
};

// cos(2 pi t) and sin(2 pi t): a per-pixel rotation from a noise value t (any float of
// moderate size; noise01's in [0, 1)). Within 1e-7 of the exact values (measured at every
// noise01 value), a quarter of the library's sincos time: the nearest quarter turn is
// taken out, and the rest, within pi/4 of it, goes through the Taylor series to x^9 and
// x^10 (truncation < 3e-9).
inline void sincos_turns(float t, float& cos_out, float& sin_out) {
  const float quarter = std::nearbyint(4.0f * t);
  const float x = (4.0f * t - quarter) * 1.57079632679489662f;  // [-pi/4, pi/4]
  const float x2 = x * x;
  const float s =
      x * (1.0f + x2 * (-1.0f / 6.0f + x2 * (1.0f / 120.0f + x2 * (-1.0f / 5040.0f + x2 * (1.0f / 362880.0f)))));
  const float c = 1.0f + x2 * (-0.5f + x2 * (1.0f / 24.0f + x2 * (-1.0f / 720.0f +
                                                                 x2 * (1.0f / 40320.0f + x2 * (-1.0f / 3628800.0f)))));
  // Rotated by the quarter turns taken out (selects, not a switch: callers run it in
  // vector lanes).
  const int q = int(quarter) & 3;
  cos_out = q == 0 ? c : q == 1 ? -s : q == 2 ? -c : s;
  sin_out = q == 0 ? s : q == 1 ? c : q == 2 ? -s : -c;
}

}  // namespace ssdo
