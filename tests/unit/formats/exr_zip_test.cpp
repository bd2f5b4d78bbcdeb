// The ZIP block codec against OpenEXR's own: chunks OpenEXR compressed inflate to the packed
// bytes of the known pixels, and our streams survive the round trip.
#include "formats/exr_zip.h"

#include <cstring>
#include <random>
#include <thread>

#include <Imath/half.h>
#include <OpenEXR/openexr.h>
#include <gtest/gtest.h>

#include "tests/support/each_simd_target.h"
#include "tests/unit/formats/formats_test_util.h"

namespace ssdo {
namespace {

using test::ScratchDir;
using test::TestChannel;
using test::TestExr;

std::vector<uint8_t> pseudo_image_bytes(size_t n, unsigned seed) {
  // Smooth ramps with noise: like rendered data, compressible but not trivially.
  std::mt19937 rng(seed);
  std::vector<uint8_t> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = uint8_t((i / 7) % 251 + (rng() % 5));
  return v;
}

TEST(ExrZip, RoundTripsEveryLevelAndOddSizes) {
  for (size_t n : {1u, 2u, 3u, 17u, 4096u, 100001u}) {
    const std::vector<uint8_t> packed = pseudo_image_bytes(n, unsigned(n));
    for (int level : {exr_zip::kMinLevel, 4, exr_zip::kMaxLevel}) {
      UninitializedVector<uint8_t> compressed;
      if (!exr_zip::compress(packed, level, compressed)) {
        EXPECT_LT(n, 64u) << "only tiny blocks may fail to shrink";
        continue;
      }
      EXPECT_LT(compressed.size(), n);
      std::vector<uint8_t> back(n);
      ASSERT_TRUE(exr_zip::decompress(compressed, back)) << n << " bytes, level " << level;
      EXPECT_EQ(back, packed) << n << " bytes, level " << level;
    }
  }
}

// The byte split and predictor run on the dispatched instruction set: every target this
// CPU runs deflates the same bytes (the first target's stream), and inflates them back,
// for sizes with every kind of tail after the vectors.
TEST(ExrZip, EveryInstructionSetGivesTheSameStreams) {
  for (size_t n : {4096u, 4097u, 4111u, 4127u, 4129u, 100001u}) {
    const std::vector<uint8_t> packed = pseudo_image_bytes(n, unsigned(n) + 1);
    std::vector<uint8_t> first;
    test::for_each_simd_target([&](const std::string& target) {
      UninitializedVector<uint8_t> compressed;
      ASSERT_TRUE(exr_zip::compress(packed, 4, compressed)) << target << ", " << n << " bytes";
      const std::vector<uint8_t> stream(compressed.begin(), compressed.end());
      if (first.empty()) first = stream;
      EXPECT_EQ(stream, first) << target << ", " << n << " bytes";
      std::vector<uint8_t> back(n);
      ASSERT_TRUE(exr_zip::decompress(compressed, back)) << target << ", " << n << " bytes";
      EXPECT_EQ(back, packed) << target << ", " << n << " bytes";
    });
  }
}

// Leaves the stack below the caller's frame full of bytes that are not zero.
[[gnu::noinline]] void dirty_stack(unsigned seed) {
  volatile uint8_t bytes[64 * 1024];
  for (size_t i = 0; i < sizeof(bytes); ++i) bytes[i] = uint8_t(seed * 131u + i * 7u + 1u);
}

// Within a process, a stream is a function of the packed bytes and the level alone: not of
// what the thread compressed before (its compressor's buffers), nor of which thread
// compresses it (the writer deflates a file's chunks on whichever pool thread takes them).
// Across processes ISA-L's level 1 rarely picks another match (docs/performance.md,
// "Output codecs"), which no test of one process can see.
TEST(ExrZip, StreamsDependOnTheBytesAloneNotOnEarlierChunks) {
  const std::vector<uint8_t> packed = pseudo_image_bytes(122880, 7u);
  for (int level : {exr_zip::kFastestLevel, 4}) {
    SCOPED_TRACE(level);
    UninitializedVector<uint8_t> first;
    ASSERT_TRUE(exr_zip::compress(packed, level, first));
    const std::vector<uint8_t> expected(first.begin(), first.end());
    auto same_after = [&](unsigned seed) {
      // Other chunks first, of other sizes and contents (a constant run, noise, smaller and
      // larger blocks), then the same bytes again.
      std::mt19937 rng(seed);
      for (int k = 0; k < 6; ++k) {
        std::vector<uint8_t> other = pseudo_image_bytes(size_t(4096 + rng() % 200000), rng());
        if (k % 3 == 1) std::fill(other.begin(), other.begin() + other.size() / 2, uint8_t(0));
        if (k % 3 == 2) for (uint8_t& b : other) b = uint8_t(rng());
        UninitializedVector<uint8_t> scratch;
        exr_zip::compress(other, level, scratch);
      }
      dirty_stack(seed);
      UninitializedVector<uint8_t> again;
      EXPECT_TRUE(exr_zip::compress(packed, level, again));
      return std::vector<uint8_t>(again.begin(), again.end()) == expected;
    };
    for (unsigned seed = 1; seed <= 4; ++seed) EXPECT_TRUE(same_after(seed)) << "this thread, seed " << seed;
    bool on_other_thread = false;
    std::thread([&] { on_other_thread = same_after(9u); }).join();
    EXPECT_TRUE(on_other_thread);
  }
}

TEST(ExrZip, IncompressibleBlocksAreReportedForRawStorage) {
  std::mt19937 rng(7);
  std::vector<uint8_t> noise(4096);
  for (auto& b : noise) b = uint8_t(rng());
  UninitializedVector<uint8_t> compressed;
  EXPECT_FALSE(exr_zip::compress(noise, 1, compressed));
}

TEST(ExrZip, DamagedOrWrongSizedStreamsAreRefused) {
  const std::vector<uint8_t> packed = pseudo_image_bytes(10000, 3);
  UninitializedVector<uint8_t> compressed;
  ASSERT_TRUE(exr_zip::compress(packed, 1, compressed));
  std::vector<uint8_t> too_small(packed.size() - 1), too_large(packed.size() + 1);
  EXPECT_FALSE(exr_zip::decompress(compressed, too_small));
  EXPECT_FALSE(exr_zip::decompress(compressed, too_large));
  std::vector<uint8_t> damaged(compressed.begin(), compressed.end());
  damaged.resize(damaged.size() / 2);
  std::vector<uint8_t> back(packed.size());
  EXPECT_FALSE(exr_zip::decompress(damaged, back));
}

// A chunk OpenEXR deflated (ZIP, 16 scanlines) inflates to the packed bytes of the pixels:
// per scanline, each channel in name order, HALF samples little-endian.
TEST(ExrZip, InflatesChunksOpenExrWrote) {
  ScratchDir dir;
  const int w = 37, h = 16;
  TestExr exr;
  exr.width = w;
  exr.height = h;
  TestChannel a{"A", OIIO::TypeDesc::HALF, {}}, b{"B", OIIO::TypeDesc::HALF, {}};
  for (int i = 0; i < w * h; ++i) {
    a.values.push_back(float(i % 97) * 0.25f);
    b.values.push_back(float((i * 13) % 61) - 30.0f);
  }
  exr.channels = {a, b};
  exr.compression = "zip";
  ASSERT_TRUE(exr.write(dir / "zip.exr"));

  exr_context_t ctx = nullptr;
  ASSERT_EQ(exr_start_read(&ctx, (dir / "zip.exr").c_str(), nullptr), EXR_ERR_SUCCESS);
  exr_chunk_info_t chunk{};
  ASSERT_EQ(exr_read_scanline_chunk_info(ctx, 0, 0, &chunk), EXR_ERR_SUCCESS);
  EXPECT_EQ(chunk.compression, EXR_COMPRESSION_ZIP);
  ASSERT_EQ(chunk.unpacked_size, uint64_t(w) * h * 2 * 2);
  std::vector<uint8_t> stream(chunk.packed_size);
  ASSERT_EQ(exr_read_chunk(ctx, 0, &chunk, stream.data()), EXR_ERR_SUCCESS);
  exr_finish(&ctx);
  ASSERT_LT(stream.size(), chunk.unpacked_size) << "test data must compress";

  std::vector<uint8_t> packed(chunk.unpacked_size);
  ASSERT_TRUE(exr_zip::decompress(stream, packed));
  for (int y = 0; y < h; ++y)
    for (int c = 0; c < 2; ++c)
      for (int x = 0; x < w; ++x) {
        const size_t at = (size_t(y) * 2 * w + size_t(c) * w + x) * 2;
        uint16_t bits;
        std::memcpy(&bits, &packed[at], 2);
        const float expected = (c == 0 ? a : b).values[size_t(y) * w + x];
        Imath::half value;
        value.setBits(bits);
        EXPECT_EQ(float(value), expected) << "x " << x << " y " << y;
      }
  // And our stream of the same bytes inflates back to them.
  UninitializedVector<uint8_t> ours;
  std::vector<uint8_t> back(packed.size());
  ASSERT_TRUE(exr_zip::compress(packed, 1, ours));
  ASSERT_TRUE(exr_zip::decompress(ours, back));
  EXPECT_EQ(back, packed);
}

}  // namespace
}  // namespace ssdo
