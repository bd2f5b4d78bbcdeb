// check_exr_headers: hand-built EXR files (valid, then each field damaged), the shared
// frames and conformance files, and the fuzzer's inputs that made OpenEXR allocate
// gigabytes from a few hundred bytes of header.
#include "formats/exr_header_check.h"

#include <chrono>
#include <cstring>

#include "formats/gbuffer_reader.h"
#include "formats_test_util.h"

namespace ssdo::test {
namespace {

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

std::string i32(int32_t v) {
  std::string s(4, '\0');
  for (int i = 0; i < 4; ++i) s[i] = char((uint32_t(v) >> (8 * i)) & 0xff);
  return s;
}
std::string u64(uint64_t v) {
  std::string s(8, '\0');
  for (int i = 0; i < 8; ++i) s[i] = char((v >> (8 * i)) & 0xff);
  return s;
}
std::string f32(float v) {
  uint32_t u;
  std::memcpy(&u, &v, 4);
  return i32(int32_t(u));
}
std::string cstr(const std::string& s) { return s + '\0'; }

// One attribute as stored: name, type, declared size, value.
std::string attribute(const std::string& name, const std::string& type, const std::string& value,
                      int64_t declared = -1) {
  return cstr(name) + cstr(type) + i32(int32_t(declared < 0 ? int64_t(value.size()) : declared)) + value;
}

std::string chlist(const std::vector<std::pair<std::string, int>>& channels) {
  std::string v;
  for (const auto& [name, type] : channels)
    v += cstr(name) + i32(type) + std::string(4, '\0') + i32(1) + i32(1);
  return v + '\0';
}

std::string box(int x0, int y0, int x1, int y1) { return i32(x0) + i32(y0) + i32(x1) + i32(y1); }

// A single-part, uncompressed, scanline EXR with float channels, written byte by byte
// (OpenEXR's file layout: magic, version, header, line offsets, chunks). `extra` is
// appended to the header's attributes; `replace` swaps a standard attribute for a
// damaged one.
struct HandExr {
  int width = 3, height = 2;
  std::vector<std::string> channels{"Z"};
  std::string extra;
  std::map<std::string, std::string> replace;
  uint32_t version = 2;

  float value(int c, int x, int y) const { return 1.0f + float(c) + 0.5f * float(x) + 2.0f * float(y); }

  std::string header() const {
    std::vector<std::pair<std::string, int>> ch;
    for (const auto& c : channels) ch.push_back({c, 2});
    std::vector<std::pair<std::string, std::string>> attrs = {
        {"channels", attribute("channels", "chlist", chlist(ch))},
        {"compression", attribute("compression", "compression", std::string(1, '\0'))},
        {"dataWindow", attribute("dataWindow", "box2i", box(0, 0, width - 1, height - 1))},
        {"displayWindow", attribute("displayWindow", "box2i", box(0, 0, width - 1, height - 1))},
        {"lineOrder", attribute("lineOrder", "lineOrder", std::string(1, '\0'))},
        {"pixelAspectRatio", attribute("pixelAspectRatio", "float", f32(1.0f))},
        {"screenWindowCenter", attribute("screenWindowCenter", "v2f", f32(0) + f32(0))},
        {"screenWindowWidth", attribute("screenWindowWidth", "float", f32(1.0f))}};
    std::string h;
    for (const auto& [name, bytes] : attrs) {
      auto it = replace.find(name);
      h += it == replace.end() ? bytes : it->second;
    }
    return h + extra + '\0';
  }

  std::string bytes() const {
    std::string file = i32(20000630) + i32(int32_t(version)) + header();
    const size_t table = file.size();
    file += std::string(8 * size_t(height), '\0');
    std::vector<std::string> sorted = channels;  // OpenEXR stores channels by name
    std::sort(sorted.begin(), sorted.end());
    for (int y = 0; y < height; ++y) {
      const std::string offset = u64(file.size());
      std::copy(offset.begin(), offset.end(), file.begin() + std::ptrdiff_t(table + 8 * size_t(y)));
      std::string data;
      for (const auto& name : sorted) {
        const int c = int(std::find(channels.begin(), channels.end(), name) - channels.begin());
        for (int x = 0; x < width; ++x) data += f32(value(c, x, y));
      }
      file += i32(y) + i32(int32_t(data.size())) + data;
    }
    return file;
  }

  fs::path write(const ScratchDir& dir, const std::string& name) const {
    const fs::path p = dir / name;
    std::ofstream(p, std::ios::binary) << bytes();
    return p;
  }
};

ReadOptions fov_options() {
  ReadOptions o;
  o.fov_x_deg = 60.0f;
  return o;
}

TEST(ExrHeaderCheck, HandBuiltFileIsValidAndReadsBack) {
  ScratchDir dir;
  HandExr e;
  const fs::path p = e.write(dir, "valid.exr");
  const ExrHeaderCheck c = check_exr_headers(p.string());
  ASSERT_TRUE(c.ok()) << c.error;
  ASSERT_EQ(c.parts.size(), 1u);
  EXPECT_EQ(c.parts[0].type, "scanlineimage");
  EXPECT_EQ(c.parts[0].max_x, 2);
  EXPECT_EQ(c.parts[0].max_y, 1);
  EXPECT_EQ(c.parts[0].compression, 0);
  EXPECT_EQ(c.parts[0].channels, 1);
  EXPECT_EQ(c.parts[0].bytes_per_pixel, 4);
  EXPECT_EQ(c.parts[0].chunks, 2);
  EXPECT_EQ(c.file_bytes, int64_t(fs::file_size(p)));
  EXPECT_EQ(c.header_bytes + 2 * 8 + 2 * (8 + 3 * 4), c.file_bytes);

  // OpenEXR reads it as written: depth is the Z values.
  const ReadResult r = read_gbuffer(p.string(), fov_options());
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_EQ(r.gbuffer.depth_view.cols, 3);
  ASSERT_EQ(r.gbuffer.depth_view.rows, 2);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x)
      EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(y, x), e.value(0, x, y)) << x << "," << y;
}

// The fuzzer's case: a string attribute declaring 1.6 GB, which OpenEXR 3.1 allocated and
// zero-filled (26 s and 2 GB under ASan) before finding the file too short.
TEST(ExrHeaderCheck, AttributeLargerThanTheFileIsRefusedWithoutAllocating) {
  ScratchDir dir;
  HandExr e;
  e.extra = cstr("comments") + cstr("string") + i32(0x63000000) + "tail";
  const fs::path p = e.write(dir, "huge_string.exr");
  const auto start = std::chrono::steady_clock::now();
  const ReadResult r = read_gbuffer(p.string(), fov_options());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, p.string())) << r.error;
  EXPECT_TRUE(contains(r.error, "attribute \"comments\" (string) declares 1660944384 bytes")) << r.error;
  EXPECT_TRUE(contains(r.error, "only " + std::to_string(4 + 1 + 2 * 8 + 2 * (8 + 12)) + " bytes of the file follow"))
      << r.error;
  EXPECT_LT(seconds, 2.0);  // was 26 s under ASan (a 1.6 GB allocation filled with zeros)

  const ReadResult info = inspect_gbuffer(p.string(), fov_options());
  EXPECT_EQ(info.error, r.error);
}

TEST(ExrHeaderCheck, DeclaredSizesMustMatchWhatOpenExrReads) {
  ScratchDir dir;
  {  // a box2i declared as 20 bytes: OpenEXR reads 16 and the rest of the header shifts
    HandExr e;
    e.replace["dataWindow"] = attribute("dataWindow", "box2i", box(0, 0, 2, 1) + i32(0), 20);
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "box.exr").string());
    EXPECT_TRUE(contains(c.error, "attribute \"dataWindow\" (box2i) declares 20 bytes; a box2i value is 16"))
        << c.error;
  }
  {  // a channel list whose terminator comes before its declared end
    HandExr e;
    e.replace["channels"] = attribute("channels", "chlist", chlist({{"Z", 2}}) + "xyz");
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "chlist.exr").string());
    EXPECT_TRUE(contains(c.error, "the channel list ends after 19 of its declared 22 bytes")) << c.error;
  }
  {  // an unknown pixel type
    HandExr e;
    e.replace["channels"] = attribute("channels", "chlist", chlist({{"Z", 43}}));
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "type.exr").string());
    EXPECT_TRUE(contains(c.error, "channel \"Z\" has pixel type 43")) << c.error;
  }
  {  // a predefined attribute of another type
    HandExr e;
    e.replace["compression"] = attribute("compression", "int", i32(0));
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "comp.exr").string());
    EXPECT_TRUE(contains(c.error, "\"compression\" must be of type compression")) << c.error;
  }
  {  // a negative size
    HandExr e;
    e.extra = cstr("note") + cstr("string") + i32(-5);
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "neg.exr").string());
    EXPECT_TRUE(contains(c.error, "attribute \"note\" (string) declares a negative size (-5)")) << c.error;
  }
  {  // a name without a terminator in 254 characters, printed escaped and shortened
    HandExr e;
    e.extra = std::string(300, '\x01');
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "name.exr").string());
    EXPECT_TRUE(contains(c.error, "\\x01\\x01")) << c.error;
    EXPECT_TRUE(contains(c.error, "has no terminator within 254 characters")) << c.error;
    EXPECT_LT(c.error.size(), 600u);
  }
  {  // ID manifests: OpenEXR 3.1 reads 4 bytes past their declared size
    HandExr e;
    e.extra = attribute("manifest", "idmanifest", u64(10) + "abcd");
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "idm.exr").string());
    EXPECT_TRUE(contains(c.error, "attribute \"manifest\" (idmanifest)")) << c.error;
  }
  {  // unknown version flags
    HandExr e;
    e.version = 2 | 0x4000;
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "flags.exr").string());
    EXPECT_TRUE(contains(c.error, "unknown flags in the version field (0x4000)")) << c.error;
  }
}

TEST(ExrHeaderCheck, OffsetTablesAndUncompressedPixelsMustFitInTheFile) {
  ScratchDir dir;
  {  // chunkCount 2^31 - 1: OpenEXR sizes the offset table from it
    HandExr e;
    e.extra = attribute("chunkCount", "int", i32(INT32_MAX));
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "chunks.exr").string());
    EXPECT_TRUE(contains(c.error, "chunkCount 2147483647, but the data window, compression and tiling give 2 chunks"))
        << c.error;
  }
  {  // a data window of 1 x 2^20 lines: 8 MiB of line offsets in a file of 200 bytes
    HandExr e;
    e.replace["dataWindow"] = attribute("dataWindow", "box2i", box(0, 0, 0, (1 << 20) - 1));
    const fs::path p = e.write(dir, "tall.exr");
    const ExrHeaderCheck c = check_exr_headers(p.string());
    EXPECT_TRUE(contains(c.error, "1048576 chunks: their offset table (8 bytes each) ends at byte")) << c.error;
    EXPECT_TRUE(contains(c.error, "past the end of the file (" + std::to_string(fs::file_size(p)) + " bytes; truncated or damaged)"))
        << c.error;
  }
  {  // 100000 x 2 uncompressed float pixels (800000 bytes) in a file of 200 bytes
    HandExr e;
    e.replace["dataWindow"] = attribute("dataWindow", "box2i", box(0, 0, 99999, 1));
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "wide.exr").string());
    EXPECT_TRUE(contains(c.error, "uncompressed pixels of data window 100000x2 (4 bytes per pixel) need 800000 bytes"))
        << c.error;
  }
}

TEST(ExrHeaderCheck, LimitsApplyToEveryBlockOpenExrAllocates) {
  ScratchDir dir;
  {  // the data window
    HandExr e;
    e.width = 64, e.height = 64;
    ExrLimits limits;
    limits.max_pixels = 4095;
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "window.exr").string(), limits);
    EXPECT_TRUE(contains(c.error, "data window 64x64 at (0, 0) refused: 4096 pixels (limit 4095 pixels)"))
        << c.error;
  }
  {  // every channel of the part counts, those not read too: 300 float channels
    HandExr e;
    e.width = 8, e.height = 8;
    e.channels.clear();
    for (int i = 0; i < 300; ++i) e.channels.push_back("c" + std::to_string(i));
    ExrLimits limits;
    limits.max_decoded_bytes = 64 * 1000;
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "channels.exr").string(), limits);
    EXPECT_TRUE(contains(c.error, "data window 8x8 at (0, 0) refused: 300 channels of 1200 bytes per pixel "
                                  "decode to 76800 bytes (limit 64000 bytes)"))
        << c.error;
    limits.max_decoded_bytes = 76800;
    EXPECT_TRUE(check_exr_headers((dir / "channels.exr").string(), limits).ok());
  }
  {  // a ZIP chunk is 16 lines: OpenEXR's compressor for a 1-line, 5000-pixel image holds 16
    HandExr e;
    e.width = 5000, e.height = 1;
    e.replace["compression"] = attribute("compression", "compression", std::string(1, '\3'));
    ExrLimits limits;
    limits.max_pixels = 50000;
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "zip.exr").string(), limits);
    EXPECT_TRUE(contains(c.error, "chunks of 16 lines of the 5000-pixel data window refused: 80000 pixels"))
        << c.error;
  }
  {  // tiles of 1 x 2^30 on a 3 x 2 image
    HandExr e;
    e.version = 2 | 0x200;
    e.extra = attribute("tiles", "tiledesc", i32(1) + i32(1 << 30) + std::string(1, '\0'));
    const ExrHeaderCheck c = check_exr_headers(e.write(dir, "tiles.exr").string());
    EXPECT_TRUE(contains(c.error, "tiles of 1x1073741824 refused: 1073741824 pixels (limit 67108864 pixels)"))
        << c.error;
  }
}

TEST(ExrHeaderCheck, PartsAreNamedByNumber) {
  ScratchDir dir;
  HandExr e;
  e.version = 2 | 0x1000;
  const std::string part0 = e.header();  // lacks a type: refused, and named part 0
  std::string file = i32(20000630) + i32(int32_t(e.version)) + part0 + '\0';
  const fs::path p = dir / "multi.exr";
  std::ofstream(p, std::ios::binary) << file;
  const ExrHeaderCheck c = check_exr_headers(p.string());
  EXPECT_EQ(c.error, p.string() + ": part 0: no type attribute (every part of a multi-part file needs one)");
}

TEST(ExrHeaderCheck, SharedFramesAndValidConformanceFilesPass) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.exr");
  const ExrHeaderCheck cornell = check_exr_headers((gbuffer_dir() / "cornell.exr").string());
  ASSERT_TRUE(cornell.ok()) << cornell.error;
  ASSERT_EQ(cornell.parts.size(), 1u);
  EXPECT_EQ(cornell.parts[0].max_x, 639);
  EXPECT_EQ(cornell.parts[0].max_y, 359);
  EXPECT_EQ(cornell.parts[0].channels, 26);
  EXPECT_EQ(cornell.parts[0].bytes_per_pixel, 19 * 2 + 7 * 4);  // 19 half, 7 float channels

  int checked = 0;
  for (const fs::path& root : {gbuffer_dir(), conformance_dir() / "valid"}) {
    if (!fs::exists(root)) continue;
    for (const auto& f : fs::recursive_directory_iterator(root)) {
      if (f.path().extension() != ".exr") continue;
      const ExrHeaderCheck c = check_exr_headers(f.path().string());
      EXPECT_TRUE(c.ok()) << c.error;
      ++checked;
    }
  }
  EXPECT_GE(checked, 30);
}

// Inputs of tests/fuzz/gbuffer_reader_fuzz.cpp that took seconds and gigabytes, kept in
// tests/data/fuzz/gbuffer_reader/: each is now refused from its header, quickly.
TEST(ExrHeaderCheck, FuzzerSlowInputsAreQuickErrors) {
  const fs::path dir = fs::path(SSDO_SOURCE_DIR) / "tests" / "data" / "fuzz" / "gbuffer_reader";
  const std::map<std::string, std::string> expected = {
      // part 1's channel R has pixel type 43, its name attribute declares 1.6 GB
      {"slow-unit-831d46cd4a7e1049a56ed2681f412fcf8faecc6c", "part 1: attribute \"channels\" (chlist): channel \"R\" has pixel type 43 (0 uint, 1 half, 2 float)"},
  };
  for (const auto& [name, message] : expected) {
    const fs::path p = dir / name;
    ASSERT_TRUE(fs::exists(p)) << p;
    const auto start = std::chrono::steady_clock::now();
    const ReadResult r = read_gbuffer(p.string(), fov_options());
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error, p.string() + ": " + message);
    EXPECT_LT(seconds, 2.0);
  }
}

}  // namespace
}  // namespace ssdo::test
