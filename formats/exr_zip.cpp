#include "formats/exr_zip.h"

#include <algorithm>
#include <array>
#include <memory>

#include <libdeflate.h>

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

std::vector<uint8_t>& scratch() {
  thread_local std::vector<uint8_t> s;
  return s;
}

}  // namespace

bool compress(std::span<const uint8_t> packed, int level, std::vector<uint8_t>& compressed) {
  level = std::clamp(level, kMinLevel, kMaxLevel);
  const size_t n = packed.size();
  if (n == 0) return false;
  std::vector<uint8_t>& t = scratch();
  t.resize(n);
  // Split: even-indexed bytes to the first half, odd-indexed to the second.
  const size_t half = (n + 1) / 2;
  for (size_t i = 0; i < half; ++i) t[i] = packed[2 * i];
  for (size_t i = 0; i < n / 2; ++i) t[half + i] = packed[2 * i + 1];
  // Predictor: d[i] = t[i] - t[i-1] + 128 (mod 256), from the last byte down.
  for (size_t i = n - 1; i > 0; --i) t[i] = uint8_t(int(t[i]) - int(t[i - 1]) + 128);
  libdeflate_compressor* c = compressor(level);
  if (!c) return false;
  // A stream only as large as the packed bytes is no gain: the format stores those.
  compressed.resize(n);
  const size_t size = libdeflate_zlib_compress(c, t.data(), n, compressed.data(), n - 1);
  if (size == 0) return false;
  compressed.resize(size);
  return true;
}

bool decompress(std::span<const uint8_t> compressed, std::span<uint8_t> packed) {
  const size_t n = packed.size();
  if (n == 0) return compressed.empty();
  libdeflate_decompressor* d = decompressor();
  if (!d) return false;
  std::vector<uint8_t>& t = scratch();
  t.resize(n);
  size_t actual = 0;
  if (libdeflate_zlib_decompress(d, compressed.data(), compressed.size(), t.data(), n, &actual) !=
          LIBDEFLATE_SUCCESS ||
      actual != n)
    return false;
  // Undo the predictor, then interleave the halves.
  for (size_t i = 1; i < n; ++i) t[i] = uint8_t(int(t[i - 1]) + int(t[i]) - 128);
  const size_t half = (n + 1) / 2;
  for (size_t i = 0; i < half; ++i) packed[2 * i] = t[i];
  for (size_t i = 0; i < n / 2; ++i) packed[2 * i + 1] = t[half + i];
  return true;
}

}  // namespace ssdo::exr_zip
