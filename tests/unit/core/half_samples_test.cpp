// Half-sample conversions against Imath on every instruction set this CPU runs: every value
// class, at every position in a vector of samples, and groups with and without NaNs.
#include "core/half_samples.h"

#include <cstring>
#include <random>
#include <vector>

#include <Imath/half.h>
#include <gtest/gtest.h>

#include "tests/support/each_simd_target.h"

namespace ssdo {
namespace {

uint32_t float_bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

float from_bits(uint32_t b) {
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}

TEST(HalfSamples, FloatsRoundToHalfAsImathDoesAndSaturate) {
  // Every half value, the ties halfway to the next one (round to nearest even decides)
  // and the floats just beside them, then random bit patterns (NaNs, infinities,
  // subnormals, overflow among them).
  std::vector<float> in;
  for (uint32_t h = 0; h < 65536; ++h) {
    const uint32_t b = float_bits(imath_half_to_float_table[h].f);
    for (uint32_t tie : {0u, 0x1000u, 0x0fffu, 0x1001u}) in.push_back(from_bits(b + tie));
  }
  std::mt19937 rng(21);
  for (int i = 0; i < (1 << 18); ++i) in.push_back(from_bits(uint32_t(rng())));
  std::vector<uint16_t> out(in.size() + 64);
  test::for_each_simd_target([&](const std::string& target) {
    // Offsets 0, 1, 3 and an odd count: vectors start at several alignments and end in a
    // tail.
    for (size_t offset : {0u, 1u, 3u}) {
      const int n = int(in.size() - offset - 1);
      half_samples::to_half(in.data() + offset, n, out.data());
      for (int i = 0; i < n; ++i) {
        // Beyond half's range (infinities too): +-65504, not infinity.
        const float v = in[offset + size_t(i)];
        const uint16_t expected = v >= 65520.0f ? uint16_t(0x7bff) : v <= -65520.0f ? uint16_t(0xfbff) : half(v).bits();
        ASSERT_EQ(out[size_t(i)], expected) << target << ", float bits " << std::hex << float_bits(v);
      }
    }
  });
}

TEST(HalfSamples, HalvesWidenAsImathsTableDoesAtEveryStride) {
  // Every half bit pattern once, little-endian, NaNs with every payload among them.
  std::vector<uint8_t> bytes(2 * 65536);
  for (uint32_t h = 0; h < 65536; ++h) {
    bytes[2 * h] = uint8_t(h & 0xff);
    bytes[2 * h + 1] = uint8_t(h >> 8);
  }
  test::for_each_simd_target([&](const std::string& target) {
    for (size_t pixel_floats : {1u, 3u}) {
      for (int64_t offset : {0, 5}) {
        const int64_t n = 65536 - offset;
        std::vector<float> out(size_t(n) * pixel_floats, -1.0f);
        half_samples::to_float(bytes.data() + 2 * offset, n, out.data(), pixel_floats);
        for (int64_t i = 0; i < n; ++i)
          ASSERT_EQ(float_bits(out[size_t(i) * pixel_floats]),
                    float_bits(imath_half_to_float_table[size_t(i + offset)].f))
              << target << ", half bits " << (i + offset) << ", stride " << pixel_floats;
      }
    }
  });
}

}  // namespace
}  // namespace ssdo
