#include "formats/exr_zip.h"

#include "core/simd_targets.h"  // before Highway

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "formats/exr_zip.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <array>
#include <memory>

#include <isa-l/igzip_lib.h>
#include <libdeflate.h>

// The byte transforms run over every byte of a frame (137 MB for a 1080p Cycles dump), as
// often as the codec itself: plain byte loops cost as much as libdeflate's inflate, so
// they take a vector of bytes at a time, on the best instruction set the CPU runs, with
// the scalar loops as the reference and for the tails. Byte arithmetic wraps (mod 256) on
// every target, so every target gives the same bytes.
HWY_BEFORE_NAMESPACE();
namespace ssdo::exr_zip::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

// out[0..half) = the even-indexed bytes of in, out[half..n) = the odd-indexed ones.
void split_even_odd(const uint8_t* in, size_t n, uint8_t* out) {
  const hn::ScalableTag<uint8_t> d;
  const size_t lanes = hn::Lanes(d);
  const size_t half = (n + 1) / 2;
  size_t i = 0;  // pairs done
  for (; 2 * i + 2 * lanes <= n; i += lanes) {
    hn::Vec<decltype(d)> even, odd;
    hn::LoadInterleaved2(d, in + 2 * i, even, odd);
    hn::StoreU(even, d, out + i);
    hn::StoreU(odd, d, out + half + i);
  }
  for (size_t k = i; k < half; ++k) out[k] = in[2 * k];
  for (size_t k = i; k < n / 2; ++k) out[half + k] = in[2 * k + 1];
}

// The inverse: out[2i] = in[i], out[2i + 1] = in[half + i].
void join_even_odd(const uint8_t* in, size_t n, uint8_t* out) {
  const hn::ScalableTag<uint8_t> d;
  const size_t lanes = hn::Lanes(d);
  const size_t half = (n + 1) / 2;
  size_t i = 0;
  for (; 2 * i + 2 * lanes <= n; i += lanes)
    hn::StoreInterleaved2(hn::LoadU(d, in + i), hn::LoadU(d, in + half + i), d, out + 2 * i);
  for (size_t k = i; k < half; ++k) out[2 * k] = in[k];
  for (size_t k = i; k < n / 2; ++k) out[2 * k + 1] = in[half + k];
}

// out[0] = in[0]; out[i] = in[i] - in[i-1] + 128 (mod 256).
void predict(const uint8_t* in, size_t n, uint8_t* out) {
  const hn::ScalableTag<uint8_t> d;
  const size_t lanes = hn::Lanes(d);
  const auto bias = hn::Set(d, uint8_t{128});
  out[0] = in[0];
  size_t i = 1;
  for (; i + lanes <= n; i += lanes)
    hn::StoreU(hn::Add(hn::Sub(hn::LoadU(d, in + i), hn::LoadU(d, in + i - 1)), bias), d, out + i);
  for (; i < n; ++i) out[i] = uint8_t(in[i] - in[i - 1] + 128);
}

// In place: t[i] = t[i-1] + t[i] - 128 (mod 256), i.e. a running sum of (t[i] - 128).
// Per 16-byte block: its prefix sums in 4 shifted adds (Hillis-Steele; byte shifts stay
// within 16-byte blocks on every target, hence the fixed block), plus the sum of every
// byte before it (`carry`, all lanes). The block's own total does not depend on `carry`,
// so the loop carries one add from block to block. The scalar baseline (one-lane vectors,
// no byte shifts) runs the scalar loop alone.
void unpredict(uint8_t* t, size_t n) {
  size_t i = 1;
#if HWY_TARGET != HWY_SCALAR
  const hn::Full128<uint8_t> d;
  const auto bias = hn::Set(d, uint8_t{128});
  const auto last_byte = hn::Set(d, uint8_t{15});
  auto carry = hn::Set(d, t[0]);
  for (; i + 16 <= n; i += 16) {
    auto x = hn::Sub(hn::LoadU(d, t + i), bias);
    x = hn::Add(x, hn::ShiftLeftBytes<1>(d, x));
    x = hn::Add(x, hn::ShiftLeftBytes<2>(d, x));
    x = hn::Add(x, hn::ShiftLeftBytes<4>(d, x));
    x = hn::Add(x, hn::ShiftLeftBytes<8>(d, x));
    hn::StoreU(hn::Add(x, carry), d, t + i);
    carry = hn::Add(carry, hn::TableLookupBytes(x, last_byte));
  }
#endif
  for (; i < n; ++i) t[i] = uint8_t(t[i - 1] + t[i] - 128);
}

}  // namespace

// EXR's ZIP transform of a chunk's packed bytes before deflate: the bytes split into even
// and odd halves, then the delta predictor (`split` is scratch, `predicted` the result).
void encode(const uint8_t* packed, size_t n, uint8_t* split, uint8_t* predicted) {
  split_even_odd(packed, n, split);
  predict(split, n, predicted);
}

// Its inverse after inflate, `predicted` overwritten in place.
void decode(uint8_t* predicted, size_t n, uint8_t* packed) {
  unpredict(predicted, n);
  join_even_odd(predicted, n, packed);
}

}  // namespace ssdo::exr_zip::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::exr_zip {

HWY_EXPORT(encode);
HWY_EXPORT(decode);

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

// Deflates `in` at ISA-L's level 1 into `out` (a zlib stream) unless it needs more than
// out.size() bytes. The level's hash table lives in a per-thread buffer.
bool igzip_level1(std::span<const uint8_t> in, std::span<uint8_t> out, size_t& written) {
  thread_local std::vector<uint8_t> level_buffer(ISAL_DEF_LVL1_DEFAULT);
  isal_zstream stream;
  isal_deflate_stateless_init(&stream);
  stream.level = 1;
  stream.level_buf = level_buffer.data();
  stream.level_buf_size = uint32_t(level_buffer.size());
  stream.gzip_flag = IGZIP_ZLIB;
  stream.end_of_stream = 1;
  stream.flush = NO_FLUSH;
  stream.next_in = const_cast<uint8_t*>(in.data());
  stream.avail_in = uint32_t(in.size());
  stream.next_out = out.data();
  stream.avail_out = uint32_t(out.size());
  if (isal_deflate_stateless(&stream) != COMP_OK) return false;  // STATELESS_OVERFLOW: no gain
  written = stream.total_out;
  return true;
}

std::vector<uint8_t>& scratch(int which) {
  thread_local std::vector<uint8_t> s[2];
  return s[which];
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
  HWY_DYNAMIC_DISPATCH(encode)(packed.data(), n, split.data(), predicted.data());
  // A stream only as large as the packed bytes is no gain: the format stores those.
  compressed.resize(n);
  size_t size = 0;
  if (level == kFastestLevel && n <= UINT32_MAX) {  // ISA-L counts bytes in 32 bits
    if (!igzip_level1(predicted, std::span(compressed.data(), n - 1), size)) return false;
  } else {
    libdeflate_compressor* c = compressor(level);
    if (!c) return false;
    size = libdeflate_zlib_compress(c, predicted.data(), n, compressed.data(), n - 1);
    if (size == 0) return false;
  }
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
  HWY_DYNAMIC_DISPATCH(decode)(t.data(), n, packed.data());
  return true;
}

}  // namespace ssdo::exr_zip
#endif  // HWY_ONCE
