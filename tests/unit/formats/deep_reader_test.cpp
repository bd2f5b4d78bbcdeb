// Deep parts read by read_gbuffer: hand-built deep scanline and deep tiled files (written
// with OpenEXR's deep API) flattened to the nearest sample and the next surface, the limits
// on their samples, and the damaged deep files of the conformance suite refused in-process.
#include <chrono>
#include <fstream>
#include <iterator>
#include <map>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDeepFrameBuffer.h>
#include <OpenEXR/ImfDeepScanLineOutputFile.h>
#include <OpenEXR/ImfDeepTiledOutputFile.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfTileDescriptionAttribute.h>

#include "formats/gbuffer_reader.h"
#include "formats_test_util.h"

namespace ssdo::test {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// One sample: a value per channel, by name (absent = 0).
using Sample = std::map<std::string, float>;

struct DeepExr {
  int width = 0, height = 0;
  bool tiled = false;
  std::vector<std::pair<std::string, Imf::PixelType>> channels;
  std::vector<std::vector<Sample>> pixels;  // row-major

  void write(const fs::path& path) const {
    Imf::Header header(width, height);
    header.setType(tiled ? Imf::DEEPTILE : Imf::DEEPSCANLINE);
    header.compression() = Imf::ZIPS_COMPRESSION;
    if (tiled) header.setTileDescription(Imf::TileDescription(2, 2, Imf::ONE_LEVEL));
    for (const auto& [name, type] : channels) header.channels().insert(name, Imf::Channel(type));
    std::vector<uint32_t> counts;
    for (const auto& p : pixels) counts.push_back(uint32_t(p.size()));
    // Samples in memory in the file's own type (OpenEXR does not convert deep samples on
    // writing): float, or half as Imath rounds it.
    std::vector<std::vector<char>> values(channels.size());
    std::vector<std::vector<char*>> pointers(channels.size(), std::vector<char*>(pixels.size()));
    Imf::DeepFrameBuffer fb;
    fb.insertSampleCountSlice(Imf::Slice(Imf::UINT, reinterpret_cast<char*>(counts.data()), 4, 4 * size_t(width)));
    for (size_t c = 0; c < channels.size(); ++c) {
      const auto& [name, type] = channels[c];
      const size_t bytes = type == Imf::HALF ? 2 : 4;
      for (const auto& p : pixels)
        for (const Sample& s : p) {
          const float v = s.count(name) ? s.at(name) : 0.0f;
          const Imath::half h(v);
          const char* from = type == Imf::HALF ? reinterpret_cast<const char*>(&h) : reinterpret_cast<const char*>(&v);
          values[c].insert(values[c].end(), from, from + bytes);
        }
      size_t at = 0;
      for (size_t i = 0; i < pixels.size(); ++i) {
        pointers[c][i] = values[c].data() + at * bytes;
        at += pixels[i].size();
      }
      fb.insert(name, Imf::DeepSlice(type, reinterpret_cast<char*>(pointers[c].data()), sizeof(char*),
                                     sizeof(char*) * width, bytes));
    }
    if (tiled) {
      Imf::DeepTiledOutputFile out(path.c_str(), header);
      out.setFrameBuffer(fb);
      out.writeTiles(0, out.numXTiles(0) - 1, 0, out.numYTiles(0) - 1);
    } else {
      Imf::DeepScanLineOutputFile out(path.c_str(), header);
      out.setFrameBuffer(fb);
      out.writePixels(height);
    }
  }
};

// 3 x 2 pixels covering every case of the flattening (formats/gbuffer_reader.h, "Deep parts").
DeepExr cases_frame(bool tiled) {
  DeepExr e;
  e.width = 3;
  e.height = 2;
  e.tiled = tiled;
  e.channels = {{"Z", Imf::FLOAT}, {"ZBack", Imf::FLOAT}, {"albedo.R", Imf::HALF},
                {"albedo.G", Imf::HALF}, {"albedo.B", Imf::HALF}};
  auto s = [](float z, float albedo, float zback = -1.0f) {
    return Sample{{"Z", z}, {"ZBack", zback < 0 ? z : zback}, {"albedo.R", albedo}, {"albedo.G", albedo}, {"albedo.B", albedo}};
  };
  e.pixels = {
      // Unsorted; 2.001 is the nearest surface again (within 1e-3 of 2), 3 is the next.
      {s(5, 0.5f), s(2.001f, 0.75f), s(2, 0.25f), s(3, 0.125f)},
      {},  // no sample: background
      // A volume sample 4 .. 4.5: 4.3 lies inside it, 6 is the next surface.
      {s(4.3f, 0.5f), s(4, 0.25f, 4.5f), s(6, 0.5f)},
      {s(1, 0.25f)},                                   // one surface: no back face
      {s(NAN, 0.5f), s(7, 0.25f)},                     // a sample without depth is skipped
      {s(1e10f, 0.5f)},                                // Cycles' "no hit": background
  };
  return e;
}

void expect_cases(const ReadResult& r) {
  ASSERT_TRUE(r.ok()) << r.error;
  const GBuffer& g = r.gbuffer;
  const float depth[6] = {2, kInf, 4, 1, 7, kInf};
  const float back[6] = {3, kInf, 6, kInf, kInf, kInf};
  const uint8_t mask[6] = {255, 0, 255, 255, 255, 0};
  const float albedo[6] = {0.25f, 0, 0.25f, 0.25f, 0.25f, 0.5f};
  for (int i = 0; i < 6; ++i) {
    const int x = i % 3, y = i / 3;
    EXPECT_EQ(g.mask.at<uint8_t>(y, x), mask[i]) << i;
    EXPECT_EQ(g.depth_view.at<float>(y, x), depth[i]) << i;
    EXPECT_EQ(g.depth_back_view.at<float>(y, x), back[i]) << i;
    EXPECT_EQ(g.albedo.at<cv::Vec3f>(y, x)[1], albedo[i]) << i;
  }
  EXPECT_EQ(r.info.nonfinite_pixels, 0);  // an empty pixel is background, not non-finite
  EXPECT_EQ(r.info.back_layer, "deep samples of Z");
  bool listed = false;
  for (const ChannelUse& u : r.info.uses) listed = listed || u.input == "depth_back";
  EXPECT_TRUE(listed);
}

ReadOptions fov_options() {
  ReadOptions o;
  o.fov_x_deg = 60.0f;
  return o;
}

TEST(DeepReader, ScanlineFileFlattensToNearestSampleAndNextSurface) {
  ScratchDir dir;
  cases_frame(false).write(dir / "deep.exr");
  expect_cases(read_gbuffer((dir / "deep.exr").string(), fov_options()));
}

TEST(DeepReader, TiledFileFlattensTheSameWay) {
  ScratchDir dir;
  cases_frame(true).write(dir / "deep_tiled.exr");
  expect_cases(read_gbuffer((dir / "deep_tiled.exr").string(), fov_options()));
}

TEST(DeepReader, SamplesOverTheLimitAreRefusedBeforeAllocation) {
  ScratchDir dir;
  cases_frame(false).write(dir / "deep.exr");
  ReadOptions o = fov_options();
  // 11 samples x (2 float + 3 half as stored: 14 bytes, + 5 channels read as float: 20).
  o.max_decoded_bytes = 11 * 34 - 1;
  const ReadResult r = read_gbuffer((dir / "deep.exr").string(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error.find("over the resource limits"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("11 samples of 34 bytes"), std::string::npos) << r.error;
  o.max_decoded_bytes = 11 * 34;
  EXPECT_TRUE(read_gbuffer((dir / "deep.exr").string(), o).ok());
}

TEST(DeepReader, WithoutBackLayerReadsOnlyTheNearestSample) {
  ScratchDir dir;
  cases_frame(false).write(dir / "deep.exr");
  ReadOptions o = fov_options();
  o.read_depth_back = false;
  const ReadResult r = read_gbuffer((dir / "deep.exr").string(), o);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.gbuffer.depth_back_view.empty());
  EXPECT_EQ(r.info.back_layer, "");
  EXPECT_EQ(r.gbuffer.depth_view.at<float>(0, 0), 2.0f);
}

// A deep part holding one surface per foreground pixel (an opaque render that stores the
// first hit) says nothing of what lies behind: no back layer (the kernels assume their
// thickness, as for a flat frame), with a note; one pixel with a second surface is enough
// for the layer.
TEST(DeepReader, OneSurfacePerPixelGivesNoBackLayer) {
  ScratchDir dir;
  DeepExr e;
  e.width = 2;
  e.height = 2;
  e.channels = {{"Z", Imf::FLOAT}};
  e.pixels = {{{{"Z", 2.0f}}}, {{{"Z", 3.0f}}}, {}, {{{"Z", 1e10f}}}};
  e.write(dir / "single.exr");
  const ReadResult r = read_gbuffer((dir / "single.exr").string(), fov_options());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.gbuffer.depth_back_view.empty());
  EXPECT_EQ(r.info.back_layer, "");
  for (const ChannelUse& u : r.info.uses) EXPECT_NE(u.input, "depth_back");
  bool noted = false;
  for (const std::string& n : r.info.notes)
    noted |= n.find("no back layer: the deep samples of Z hold no second surface") != std::string::npos;
  EXPECT_TRUE(noted);
  EXPECT_EQ(r.gbuffer.depth_view.at<float>(0, 1), 3.0f);

  e.pixels[1].push_back({{"Z", 4.0f}});
  e.write(dir / "second.exr");
  const ReadResult with = read_gbuffer((dir / "second.exr").string(), fov_options());
  ASSERT_TRUE(with.ok()) << with.error;
  ASSERT_FALSE(with.gbuffer.depth_back_view.empty());
  EXPECT_EQ(with.gbuffer.depth_back_view.at<float>(0, 1), 4.0f);
  EXPECT_EQ(with.gbuffer.depth_back_view.at<float>(0, 0), kInf);
  EXPECT_EQ(with.info.back_layer, "deep samples of Z");
}

// Every damaged file of the conformance suite with a deep part is refused with an error
// naming the file, in this process (no abort) and in bounded time (no hang), with the
// default inputs and with mappings that reach more of them. One is decoded: its header
// declares mip levels that OpenEXR sizes wrongly, but level 0, the one read, is whole
// (OpenEXR and oiiotool --printstats read it too); its depth channel is named "0".
TEST(DeepReader, DamagedDeepConformanceFilesAreRefusedNeverAbortOrHang) {
  const fs::path damaged = conformance_dir() / "damaged";
  SSDO_SKIP_WITHOUT(damaged);
  const std::string readable = "imf_test_deep_tile_file_fuzz_broken_exr";
  int deep_files = 0;
  for (const auto& entry : fs::directory_iterator(damaged)) {
    const std::string path = entry.path().string();
    // A deep part's "type" attribute names it (whether or not the rest of the header holds).
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes.find("deepscanline") == std::string::npos && bytes.find("deeptile") == std::string::npos) continue;
    ++deep_files;
    for (const char* depth : {"", "Z", "A", "0"}) {
      ReadOptions o = fov_options();
      o.mapping.depth = depth;
      o.max_decoded_bytes = int64_t(1) << 30;
      const auto start = std::chrono::steady_clock::now();
      const ReadResult r = read_gbuffer(path, o);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      EXPECT_LT(seconds, 5.0) << path;
      if (entry.path().filename() == readable && std::string(depth) == "0") {
        EXPECT_TRUE(r.ok()) << r.error;
        // Its samples hold one surface per pixel: no back layer, said in a note.
        EXPECT_EQ(r.info.back_layer, "");
        EXPECT_TRUE(r.gbuffer.depth_back_view.empty());
        bool noted = false;
        for (const std::string& n : r.info.notes) noted |= n.rfind("no back layer: the deep samples of 0", 0) == 0;
        EXPECT_TRUE(noted);
        continue;
      }
      EXPECT_FALSE(r.ok()) << path << " --map depth=" << depth;
      EXPECT_EQ(r.error.rfind(path, 0), 0u) << r.error;
    }
  }
  EXPECT_EQ(deep_files, 17);
}

}  // namespace
}  // namespace ssdo::test
