#include "formats/exr_zip.h"

#include <algorithm>
#include <array>
#include <memory>

#include <libdeflate.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace ssdo::exr_zip {
namespace {

struct CompressorDeleter {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};
struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

libdeflate_compressor* compressor(int level) {
  thread_local std::array<std::unique_ptr<libdeflate_compressor, CompressorDeleter>, kMaxLevel + 1>
      by_level;
  auto& c = by_level[size_t(level)];
  if (!c) c.reset(libdeflate_alloc_compressor(level));
  return c.get();
}

libdeflate_decompressor* decompressor() {
  thread_local std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> d;
  if (!d) d.reset(libdeflate_alloc_decompressor());
  return d.get();
}

std::vector<uint8_t>& scratch(int which) {
  thread_local std::vector<uint8_t> s[2];
  return s[which];
}

// The byte transforms run over every byte of a frame (137 MB for a 1080p Cycles dump), as
// often as the codec itself: plain byte loops cost as much as libdeflate's inflate, so
// they use 16 bytes at a time (SSE2, the x86-64 baseline) with the scalar loops as the
// reference and for the tails.

// out[0..half) = the even-indexed bytes of in, out[half..n) = the odd-indexed ones.
void split_even_odd(const uint8_t* in, size_t n, uint8_t* out) {
  const size_t half = (n + 1) / 2;
  size_t i = 0;  // pairs done
#if defined(__SSE2__)
  const __m128i low = _mm_set1_epi16(0x00ff);
  for (; 2 * i + 32 <= n; i += 16) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + 2 * i));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + 2 * i + 16));
    const __m128i even = _mm_packus_epi16(_mm_and_si128(a, low), _mm_and_si128(b, low));
    const __m128i odd = _mm_packus_epi16(_mm_srli_epi16(a, 8), _mm_srli_epi16(b, 8));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), even);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + half + i), odd);
  }
#endif
  for (size_t k = i; k < half; ++k) out[k] = in[2 * k];
  for (size_t k = i; k < n / 2; ++k) out[half + k] = in[2 * k + 1];
}

// The inverse: out[2i] = in[i], out[2i + 1] = in[half + i].
void join_even_odd(const uint8_t* in, size_t n, uint8_t* out) {
  const size_t half = (n + 1) / 2;
  size_t i = 0;
#if defined(__SSE2__)
  for (; 2 * i + 32 <= n; i += 16) {
    const __m128i even = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i));
    const __m128i odd = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + half + i));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + 2 * i), _mm_unpacklo_epi8(even, odd));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + 2 * i + 16), _mm_unpackhi_epi8(even, odd));
  }
#endif
  for (size_t k = i; k < half; ++k) out[2 * k] = in[k];
  for (size_t k = i; k < n / 2; ++k) out[2 * k + 1] = in[half + k];
}

// out[0] = in[0]; out[i] = in[i] - in[i-1] + 128 (mod 256). Vectorises as written.
void predict(const uint8_t* in, size_t n, uint8_t* out) {
  out[0] = in[0];
  for (size_t i = 1; i < n; ++i) out[i] = uint8_t(in[i] - in[i - 1] + 128);
}

// In place: t[i] = t[i-1] + t[i] - 128 (mod 256), i.e. a running sum of (t[i] - 128).
void unpredict(uint8_t* t, size_t n) {
  size_t i = 1;
#if defined(__SSE2__)
  // Prefix sums of 16 bytes in 4 shifted adds (Hillis-Steele), plus the previous byte.
  const __m128i bias = _mm_set1_epi8(char(-128));
  __m128i carry = _mm_set1_epi8(char(t[0]));
  for (; i + 16 <= n; i += 16) {
    __m128i x = _mm_add_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(t + i)), bias);
    x = _mm_add_epi8(x, _mm_slli_si128(x, 1));
    x = _mm_add_epi8(x, _mm_slli_si128(x, 2));
    x = _mm_add_epi8(x, _mm_slli_si128(x, 4));
    x = _mm_add_epi8(x, _mm_slli_si128(x, 8));
    x = _mm_add_epi8(x, carry);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(t + i), x);
    // Broadcast the last byte: the next block's starting value.
    __m128i last = _mm_unpackhi_epi8(x, x);              // bytes 8..15 doubled
    last = _mm_unpackhi_epi16(last, last);               // bytes 12..15 as 4x
    last = _mm_shuffle_epi32(last, _MM_SHUFFLE(3, 3, 3, 3));  // byte 15 everywhere
    carry = last;
  }
#endif
  for (; i < n; ++i) t[i] = uint8_t(t[i - 1] + t[i] - 128);
}

}  // namespace

bool compress(std::span<const uint8_t> packed, int level, UninitializedVector<uint8_t>& compressed) {
  level = std::clamp(level, kMinLevel, kMaxLevel);
  const size_t n = packed.size();
  if (n == 0) return false;
  std::vector<uint8_t>& split = scratch(0);
  std::vector<uint8_t>& predicted = scratch(1);
  split.resize(n);
  predicted.resize(n);
  split_even_odd(packed.data(), n, split.data());
  predict(split.data(), n, predicted.data());
  libdeflate_compressor* c = compressor(level);
  if (!c) return false;
  // A stream only as large as the packed bytes is no gain: the format stores those.
  compressed.resize(n);
  const size_t size = libdeflate_zlib_compress(c, predicted.data(), n, compressed.data(), n - 1);
  if (size == 0) return false;
  compressed.resize(size);
  return true;
}

bool decompress(std::span<const uint8_t> compressed, std::span<uint8_t> packed) {
  const size_t n = packed.size();
  if (n == 0) return compressed.empty();
  libdeflate_decompressor* d = decompressor();
  if (!d) return false;
  std::vector<uint8_t>& t = scratch(0);
  t.resize(n);
  size_t actual = 0;
  if (libdeflate_zlib_decompress(d, compressed.data(), compressed.size(), t.data(), n, &actual) !=
          LIBDEFLATE_SUCCESS ||
      actual != n)
    return false;
  unpredict(t.data(), n);
  join_even_odd(t.data(), n, packed.data());
  return true;
}

}  // namespace ssdo::exr_zip
