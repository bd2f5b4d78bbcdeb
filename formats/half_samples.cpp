#include "formats/half_samples.h"

#include <cstring>

#include <Imath/half.h>
#if defined(__x86_64__)
#include <cpuid.h>
#include <immintrin.h>
#endif

namespace ssdo::half_samples {
namespace {

// Imath's conversion (round to nearest even) of n consecutive floats into half bits.
void to_half_imath(const float* in, int n, uint16_t* out) {
  for (int x = 0; x < n; ++x) out[x] = half(in[x]).bits();
}

// Imath's conversion of n half samples (little-endian bits) to floats `pixel_floats` floats
// apart: its table, which OpenEXR's copyIntoFrameBuffer uses through half's float operator
// unless OpenEXR is built for F16C.
void to_float_imath(const uint8_t* from, int64_t n, float* to, size_t pixel_floats) {
  for (int64_t x = 0; x < n; ++x) {
    uint16_t bits;
    std::memcpy(&bits, from + 2 * x, 2);
    to[size_t(x) * pixel_floats] = imath_half_to_float_table[bits].f;
  }
}

#if defined(__x86_64__)
// F16C rounds to nearest even as Imath does, so every finite value and infinity converts
// to the same bits; NaNs may not (F16C quiets a signalling NaN), so a group of 8 holding a
// NaN is converted by Imath.
__attribute__((target("avx2,f16c"))) void to_half_f16c(const float* in, int n, uint16_t* out) {
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m256 v = _mm256_loadu_ps(in + x);
    if (_mm256_movemask_ps(_mm256_cmp_ps(v, v, _CMP_UNORD_Q)) != 0) {
      to_half_imath(in + x, 8, out + x);
      continue;
    }
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), _mm256_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT));
  }
  to_half_imath(in + x, n - x, out + x);
}

// F16C's conversion from half is exact, as the table is, for every finite half and
// infinity; a NaN may come out otherwise (a signalling NaN quieted), so a group of 8
// holding a NaN (exponent all ones, mantissa not 0) goes through the table.
__attribute__((target("avx2,f16c"))) void to_float_f16c(const uint8_t* from, int64_t n, float* to,
                                                        size_t pixel_floats) {
  const __m128i magnitude_bits = _mm_set1_epi16(0x7fff);
  const __m128i infinity_bits = _mm_set1_epi16(0x7c00);
  int64_t x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(from + 2 * x));
    float* out = to + size_t(x) * pixel_floats;
    // Magnitudes are at most 0x7fff, so the signed comparison is the unsigned one.
    const __m128i nan = _mm_cmpgt_epi16(_mm_and_si128(h, magnitude_bits), infinity_bits);
    if (_mm_movemask_epi8(nan) != 0) {
      to_float_imath(from + 2 * x, 8, out, pixel_floats);
      continue;
    }
    const __m256 v = _mm256_cvtph_ps(h);
    if (pixel_floats == 1) {
      _mm256_storeu_ps(out, v);
      continue;
    }
    alignas(32) float lanes[8];
    _mm256_store_ps(lanes, v);
    for (int i = 0; i < 8; ++i) out[size_t(i) * pixel_floats] = lanes[i];
  }
  to_float_imath(from + 2 * x, n - x, to + size_t(x) * pixel_floats, pixel_floats);
}

// AVX2 and F16C, detected once (cpuid: clang's __builtin_cpu_supports does not know "f16c").
bool has_f16c() {
  static const bool f16c = [] {
    unsigned a = 0, b = 0, c = 0, d = 0;
    return __builtin_cpu_supports("avx2") && __get_cpuid(1, &a, &b, &c, &d) != 0 && (c & bit_F16C) != 0;
  }();
  return f16c;
}
#endif

}  // namespace

void to_half(const float* in, int n, uint16_t* out) {
#if defined(__x86_64__)
  if (has_f16c()) return to_half_f16c(in, n, out);
#endif
  to_half_imath(in, n, out);
}

void to_float(const uint8_t* from, int64_t n, float* to, size_t pixel_floats) {
#if defined(__x86_64__)
  if (has_f16c()) return to_float_f16c(from, n, to, pixel_floats);
#endif
  to_float_imath(from, n, to, pixel_floats);
}

}  // namespace ssdo::half_samples
