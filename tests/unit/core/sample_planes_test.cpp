// Interleaved pixels split into planes (core/sample_planes.h) on every instruction set
// this CPU runs: each sample lands in its channel's plane at its pixel, for the channel
// counts with vector loops (2, 3, 4) and without (1, 5), for row lengths around the vector
// widths, and nothing past a plane's end is written.
#include "core/sample_planes.h"

#include <bit>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/each_simd_target.h"

namespace ssdo::sample_planes {
namespace {

template <class T>
T sample(uint32_t bits) {
  if constexpr (sizeof(T) == 2) return T(bits >> 16);
  else return std::bit_cast<T>(bits);
}

template <class T>
uint32_t bits_of(T v) {
  if constexpr (sizeof(T) == 2) return v;
  else return std::bit_cast<uint32_t>(v);
}

template <class T>
void expect_split(int channels, int64_t n, const std::string& target) {
  std::vector<T> pixels(size_t(n * channels));
  // Distinct samples; as floats, bit patterns of every kind (NaNs with payloads among them).
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = sample<T>(0x9E3779B9u * uint32_t(i) + 1u);
  const T kUnwritten = sample<T>(0xABCD1234u);
  const int64_t guard = 8;  // samples after each plane that must stay unwritten
  std::vector<T> planes(size_t(channels * (n + guard)), kUnwritten);
  std::vector<T*> to;
  for (int c = 0; c < channels; ++c) to.push_back(planes.data() + c * (n + guard));
  split(pixels.data(), n, channels, to.data());
  for (int c = 0; c < channels; ++c) {
    for (int64_t x = 0; x < n; ++x)
      ASSERT_EQ(bits_of(to[size_t(c)][x]), bits_of(pixels[size_t(x * channels + c)]))
          << target << ": " << sizeof(T) << "-byte samples, " << channels << " channels, n " << n << ", x " << x;
    for (int64_t x = n; x < n + guard; ++x)
      ASSERT_EQ(bits_of(to[size_t(c)][x]), bits_of(kUnwritten)) << target << ": written past the plane's end at " << x;
  }
}

TEST(SamplePlanes, EverySampleLandsInItsChannelsPlane) {
  test::for_each_simd_target([](const std::string& target) {
    for (int channels = 1; channels <= 5; ++channels)
      for (const int64_t n : {0, 1, 3, 7, 8, 15, 16, 17, 31, 32, 33, 64, 100, 1920}) {
        expect_split<uint16_t>(channels, n, target);
        expect_split<float>(channels, n, target);
      }
  });
}

}  // namespace
}  // namespace ssdo::sample_planes
