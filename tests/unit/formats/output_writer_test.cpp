// write_outputs: channel names and types, values after a round trip, camera attributes read
// back by the reader, compression rules, temp file + rename, PNG previews.
#include "formats/output_writer.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/openexr.h>

#include "formats/gbuffer_reader.h"
#include "core/half_samples.h"
#include "formats_test_util.h"

namespace ssdo::test {
namespace {

cv::Mat ramp(int w, int h, int channels, float scale, float offset) {
  cv::Mat m(h, w, CV_32FC(channels));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c)
        m.ptr<float>(y)[x * channels + c] = offset + scale * float(y * w * channels + x * channels + c);
  return m;
}

Camera test_camera(int w, int h) {
  Camera cam = Camera::from_fov_x(w, h, 55.0f, 0.1f, 500.0f);
  // A rotated and translated camera: about 30 degrees around Y, then up 1.5 and back 4.
  const float a = glm::radians(30.0f);
  glm::mat4 view_to_world(1.0f);
  view_to_world[0] = glm::vec4(std::cos(a), 0, -std::sin(a), 0);
  view_to_world[2] = glm::vec4(std::sin(a), 0, std::cos(a), 0);
  view_to_world[3] = glm::vec4(0.5f, 1.5f, 4.0f, 1);
  cam.view_to_world = view_to_world;
  cam.world_to_view = glm::inverse(view_to_world);
  return cam;
}

std::vector<std::string> channel_names(const fs::path& path, std::vector<OIIO::TypeDesc>* types = nullptr) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) return {};
  if (types) {
    types->clear();
    for (int c = 0; c < in->spec().nchannels; ++c) types->push_back(in->spec().channelformat(c));
  }
  return in->spec().channelnames;
}

size_t files_in(const fs::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

// Every channel of an EXR as OpenEXR decodes it, in its stored type: the sample bits.
std::map<std::string, std::vector<uint8_t>> stored_samples(const fs::path& path) {
  Imf::InputFile in(path.c_str());
  const Imath::Box2i window = in.header().dataWindow();
  const size_t w = size_t(window.max.x - window.min.x + 1), h = size_t(window.max.y - window.min.y + 1);
  std::map<std::string, std::vector<uint8_t>> samples;
  Imf::FrameBuffer fb;
  for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
    const size_t bytes = it.channel().type == Imf::HALF ? 2 : 4;
    std::vector<uint8_t>& s = samples[it.name()];
    s.resize(w * h * bytes);
    // Addressed by absolute pixel: the buffer's first sample is the data window's corner.
    char* base = reinterpret_cast<char*>(s.data()) - ptrdiff_t(window.min.x) * ptrdiff_t(bytes) -
                 ptrdiff_t(window.min.y) * ptrdiff_t(bytes * w);
    fb.insert(it.name(), Imf::Slice(it.channel().type, base, bytes, bytes * w));
  }
  in.setFrameBuffer(fb);
  in.readPixels(window.min.y, window.max.y);
  return samples;
}

// Every header attribute of an EXR: its type name and its value as the file stores it.
std::map<std::string, std::string> header_attributes(const fs::path& path) {
  Imf::InputFile in(path.c_str());
  std::map<std::string, std::string> attributes;
  for (auto it = in.header().begin(); it != in.header().end(); ++it) {
    Imf::StdOSStream value;
    it.attribute().writeValueTo(value, in.version());
    attributes[it.name()] = std::string(it.attribute().typeName()) + ": " + value.str();
  }
  attributes["(version field)"] = std::to_string(in.version());
  return attributes;
}

// Chunks of a one-part scanline EXR stored uncompressed (packed size = unpacked size) and
// compressed, read with OpenEXRCore.
std::pair<int, int> raw_and_compressed_chunks(const fs::path& path) {
  exr_context_t ctx = nullptr;
  if (exr_start_read(&ctx, path.c_str(), nullptr) != EXR_ERR_SUCCESS) return {-1, -1};
  exr_attr_box2i_t window;
  int32_t lines = 0;
  exr_get_data_window(ctx, 0, &window);
  exr_get_scanlines_per_chunk(ctx, 0, &lines);
  int raw = 0, compressed = 0;
  for (int y = window.min.y; y <= window.max.y; y += lines) {
    exr_chunk_info_t info;
    if (exr_read_scanline_chunk_info(ctx, 0, y, &info) != EXR_ERR_SUCCESS) {
      raw = compressed = -1;
      break;
    }
    ++(info.packed_size == info.unpacked_size ? raw : compressed);
  }
  exr_finish(&ctx);
  return {raw, compressed};
}

// Writes `terms` with both zip encoders and expects the same header and the same stored
// samples, through OpenEXR and through OpenImageIO.
void expect_encoders_agree(const fs::path& dir, const std::string& name, const std::vector<OutputTerm>& terms,
                           const Camera& cam, WriteOptions o) {
  SCOPED_TRACE(name);
  o.chunk_encoder = ChunkEncoder::openexr;
  const fs::path reference = dir / (name + ".openexr.exr");
  ASSERT_EQ(write_outputs(reference.string(), terms, cam, o), "");
  o.chunk_encoder = ChunkEncoder::own;
  const fs::path fast = dir / (name + ".libdeflate.exr");
  ASSERT_EQ(write_outputs(fast.string(), terms, cam, o), "");

  // OpenEXRCore adds the part's "type" to every header (optional in a single-part file).
  auto fast_attributes = header_attributes(fast);
  EXPECT_EQ(fast_attributes["type"], "string: scanlineimage");
  fast_attributes.erase("type");
  EXPECT_EQ(fast_attributes, header_attributes(reference));
  const auto expected = stored_samples(reference), actual = stored_samples(fast);
  ASSERT_EQ(actual.size(), expected.size());
  for (const auto& [channel, bits] : expected) {
    ASSERT_EQ(actual.count(channel), 1u) << channel;
    EXPECT_TRUE(actual.at(channel) == bits) << channel << " differs";
  }
  std::vector<std::string> names;
  for (const auto& [channel, bits] : expected) names.push_back(channel);
  const auto oiio_expected = read_channels_oiio(reference, names), oiio_actual = read_channels_oiio(fast, names);
  ASSERT_EQ(oiio_actual.size(), oiio_expected.size());
  ASSERT_FALSE(oiio_actual.empty());
  EXPECT_EQ(std::memcmp(oiio_actual.data(), oiio_expected.data(), oiio_actual.size() * sizeof(float)), 0);
}

// Uniformly random float bits (no NaN or infinity): incompressible samples.
cv::Mat random_bits(int w, int h, int channels, uint64_t seed) {
  cv::Mat m(h, w, CV_32FC(channels));
  std::mt19937 rng{static_cast<uint32_t>(seed)};
  for (int y = 0; y < h; ++y)
    for (int i = 0; i < w * channels; ++i) {
      uint32_t bits = rng();
      if ((bits & 0x7f800000u) == 0x7f800000u) bits &= ~0x00800000u;
      std::memcpy(&m.ptr<float>(y)[i], &bits, 4);
    }
  return m;
}

TEST(WriteOutputs, EveryKindOfTermRoundTrips) {
  ScratchDir dir;
  const int w = 40, h = 24;
  const Camera cam = test_camera(w, h);
  std::vector<OutputTerm> terms = {
      {"ao", ramp(w, h, 1, 1.0f / 960.0f, 0.0f), SampleType::half, false},
      {"Z", ramp(w, h, 1, 0.37f, 1.0f), SampleType::float32, false},
      {"ssdo_direct", ramp(w, h, 3, 0.001f, 0.1f), SampleType::half, false},
      {"bent_normal", ramp(w, h, 3, -0.0005f, 0.9f), SampleType::float32, true},
  };
  const fs::path path = dir / "out.exr";
  ASSERT_EQ(write_outputs(path.string(), terms, cam), "");
  std::vector<OIIO::TypeDesc> types;
  auto names = channel_names(path, &types);
  // OpenEXR stores channels sorted by name (OpenImageIO lists R, G, B in that order).
  const std::vector<std::string> expected = {"Z", "ao", "bent_normal.X", "bent_normal.Y", "bent_normal.Z",
                                             "ssdo_direct.B", "ssdo_direct.G", "ssdo_direct.R"};
  ASSERT_EQ(names.size(), expected.size());
  for (size_t i = 0; i < names.size(); ++i) {
    const bool is_half = names[i] == "ao" || names[i].rfind("ssdo_direct.", 0) == 0;
    EXPECT_EQ(types[i], is_half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT) << names[i];
  }
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, expected);
  for (const auto& t : terms) {
    SCOPED_TRACE(t.name);
    std::vector<std::string> ch;
    if (t.image.channels() == 1) ch = {t.name};
    else if (t.vector) ch = {t.name + ".X", t.name + ".Y", t.name + ".Z"};
    else ch = {t.name + ".R", t.name + ".G", t.name + ".B"};
    const auto values = read_channels_oiio(path, ch);
    ASSERT_EQ(values.size(), size_t(w * h * t.image.channels()));
    double max_rel = 0;
    for (int i = 0; i < w * h * t.image.channels(); ++i) {
      const float v = t.image.ptr<float>()[i];
      max_rel = std::max(max_rel, std::abs(double(values[i]) - v) / std::max(1e-3, std::abs(double(v))));
    }
    // Half keeps 11 significant bits: relative error <= 2^-11.
    EXPECT_LE(max_rel, t.type == SampleType::half ? 4.9e-4 : 0.0);
  }
  // No temp file left behind.
  EXPECT_EQ(files_in(dir.path), 1u);

  // The camera comes back through the reader's header path ("Z" makes it a generic frame).
  const ReadResult r = inspect_gbuffer(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.camera_source, "header worldToCamera/worldToNDC");
  const Camera& back = r.gbuffer.camera;
  EXPECT_EQ(back.width_px, w);
  EXPECT_EQ(back.height_px, h);
  EXPECT_FLOAT_EQ(back.near_view, 0.1f);
  EXPECT_FLOAT_EQ(back.far_view, 500.0f);
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row) {
      EXPECT_NEAR(back.view_to_clip[c][row], cam.view_to_clip[c][row], 1e-5) << c << "," << row;
      EXPECT_NEAR(back.world_to_view[c][row], cam.world_to_view[c][row], 1e-5) << c << "," << row;
      EXPECT_NEAR(back.view_to_world[c][row], cam.view_to_world[c][row], 1e-5) << c << "," << row;
    }
}

// An output name near a file name's 255 bytes: its temp file's name keeps the end of it
// (the extension) and fits, so the write succeeds and leaves nothing else behind.
TEST(WriteOutputs, ANameNearTheFileNameLimitIsWritten) {
  ScratchDir dir;
  const std::string name = std::string(246, 'n') + ".ssdo.exr";  // 255 bytes
  const fs::path path = dir / name;
  const cv::Mat ao = ramp(16, 8, 1, 0.01f, 0.0f);
  ASSERT_EQ(write_outputs(path.string(), {{"ao", ao, SampleType::half}}, Camera::from_fov_x(16, 8, 60.0f)), "");
  EXPECT_TRUE(fs::exists(path));
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path)) ++files;
  EXPECT_EQ(files, 1);
  // Previews whose names would be longer than a file name may be: refused before any file
  // is written (no previews without their EXR). "P.ssdo" + ".ao.png": 243 p's make 255 bytes.
  WriteOptions previews;
  previews.png_previews = true;
  const fs::path fits = dir / (std::string(243, 'p') + ".ssdo.exr");
  EXPECT_EQ(write_outputs(fits.string(), {{"ao", ao, SampleType::half}}, Camera::from_fov_x(16, 8, 60.0f), previews), "");
  EXPECT_TRUE(fs::exists(dir / (std::string(243, 'p') + ".ssdo.ao.png")));
  const fs::path longer = dir / (std::string(244, 'p') + ".ssdo.exr");
  EXPECT_EQ(write_outputs(longer.string(), {{"ao", ao, SampleType::half}}, Camera::from_fov_x(16, 8, 60.0f), previews),
            longer.string() + ": the preview name " + std::string(244, 'p') +
                ".ssdo.ao.png is 256 bytes, over a file name's 255: shorten the frame's name, or leave out --png");
  files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path)) ++files;
  EXPECT_EQ(files, 3);  // the first, and the one that fits with its preview
}

TEST(WriteOutputs, NonContiguousImagesAreWrittenRowByRow) {
  ScratchDir dir;
  const cv::Mat big = ramp(64, 32, 1, 1.0f, 0.0f);
  const cv::Mat view = big(cv::Rect(8, 4, 16, 8));  // a ROI: row step != width
  const fs::path path = dir / "roi.exr";
  ASSERT_EQ(write_outputs(path.string(), {{"v", view, SampleType::float32}}, Camera::from_fov_x(16, 8, 60.0f)), "");
  const auto values = read_channels_oiio(path, {"v"});
  ASSERT_EQ(values.size(), 128u);
  EXPECT_EQ(values[0], big.at<float>(4, 8));
  EXPECT_EQ(values[127], big.at<float>(11, 23));
}

TEST(WriteOutputs, DwaaOnlyForColourTerms) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(16, 8, 60.0f);
  WriteOptions dwaa;
  dwaa.compression = "dwaa";
  const fs::path path = dir / "dwaa.exr";
  std::string e = write_outputs(path.string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam, dwaa);
  EXPECT_NE(e.find("dwaa"), std::string::npos) << e;
  EXPECT_NE(e.find("\"ao\""), std::string::npos) << e;
  EXPECT_NE(e.find("numeric"), std::string::npos) << e;
  e = write_outputs(path.string(), {{"bent_normal", ramp(16, 8, 3, 0.01f, 0.0f), SampleType::half, true}}, cam, dwaa);
  EXPECT_NE(e.find("vector"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(write_outputs(path.string(), {{"composite", ramp(16, 8, 3, 0.01f, 0.0f)}}, cam, dwaa), "");
  EXPECT_TRUE(fs::exists(path));
}

TEST(WriteOutputs, CompressionsAndUnknownCompression) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(16, 8, 60.0f);
  for (const char* c : {"zip", "zips", "piz", "rle", "none"}) {
    WriteOptions o;
    o.compression = c;
    const fs::path path = dir / (std::string(c) + ".exr");
    EXPECT_EQ(write_outputs(path.string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam, o), "") << c;
    auto in = OIIO::ImageInput::open(path.string());
    ASSERT_TRUE(in);
    EXPECT_EQ(in->spec().get_string_attribute("compression"), c);
  }
  WriteOptions bad;
  bad.compression = "lzma";
  const std::string e = write_outputs((dir / "bad.exr").string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam, bad);
  EXPECT_NE(e.find("unknown compression \"lzma\""), std::string::npos) << e;
}

// Every lossless compression, at any zip level and thread count, stores the same bits: the
// fast choices (rle, none, zip level 1, the default) lose nothing against OpenEXR's default
// zip level. Values with noisy mantissas, a background of zeros and non-finite samples.
TEST(WriteOutputs, LosslessCompressionsStoreTheSameBits) {
  ScratchDir dir;
  const int w = 97, h = 61;  // odd sizes: partial zip blocks and conversion strips
  const Camera cam = Camera::from_fov_x(w, h, 60.0f);
  cv::Mat ao(h, w, CV_32FC1), colour(h, w, CV_32FC3);
  cv::RNG rng(7);
  rng.fill(ao, cv::RNG::UNIFORM, 0.0f, 1.0f);
  rng.fill(colour, cv::RNG::NORMAL, 0.5f, 2.0f);
  ao(cv::Rect(0, 0, w, 9)).setTo(0.0f);
  ao.at<float>(20, 30) = std::numeric_limits<float>::infinity();
  colour.at<cv::Vec3f>(5, 6)[1] = std::numeric_limits<float>::quiet_NaN();
  colour.at<cv::Vec3f>(7, 8)[2] = 1e6f;  // beyond half: saturates at 65504
  const std::vector<OutputTerm> terms = {{"ao", ao, SampleType::float32},
                                         {"ssdo_direct", colour, SampleType::half},
                                         {"bent_normal", colour, SampleType::half, true}};
  const std::vector<std::string> names = {"ao", "ssdo_direct.R", "ssdo_direct.G", "ssdo_direct.B",
                                          "bent_normal.X", "bent_normal.Y", "bent_normal.Z"};
  struct Variant {
    const char* compression;
    int zip_level, threads;
    ChunkEncoder encoder = ChunkEncoder::own;
  };
  std::vector<std::vector<float>> stored;
  for (const Variant v : {Variant{"zip", 4, 1, ChunkEncoder::openexr}, Variant{"zip", kFastZipLevel, 2},
                          Variant{"zip", 9, 1}, Variant{"zips", 1, 0}, Variant{"zips", 1, 2, ChunkEncoder::openexr},
                          Variant{"piz", 1, 2}, Variant{"rle", 1, 2}, Variant{"none", 1, 1}}) {
    WriteOptions o;
    o.compression = v.compression;
    o.zip_level = v.zip_level;
    o.threads = v.threads;
    o.chunk_encoder = v.encoder;
    const fs::path path = dir / (std::string(v.compression) + std::to_string(v.zip_level) + "-" +
                                 std::to_string(v.threads) + "-" + std::to_string(int(v.encoder)) + ".exr");
    ASSERT_EQ(write_outputs(path.string(), terms, cam, o), "") << v.compression;
    stored.push_back(read_channels_oiio(path, names));
    ASSERT_EQ(stored.back().size(), size_t(w) * h * names.size()) << v.compression;
    EXPECT_EQ(std::memcmp(stored.back().data(), stored.front().data(), stored.front().size() * sizeof(float)), 0)
        << v.compression << " level " << v.zip_level << " differs from zip level 4";
  }
  // The float channel is stored exactly; half channels are the float values rounded to half.
  const std::vector<float>& s = stored.front();
  const size_t n = names.size();
  EXPECT_EQ(s[(size_t(20) * w + 30) * n], std::numeric_limits<float>::infinity());
  EXPECT_EQ(s[(size_t(40) * w + 41) * n], ao.at<float>(40, 41));
  EXPECT_EQ(s[(size_t(40) * w + 41) * n + 1], float(half(colour.at<cv::Vec3f>(40, 41)[0])));
  EXPECT_TRUE(std::isnan(s[(size_t(5) * w + 6) * n + 2]));
  EXPECT_EQ(s[(size_t(7) * w + 8) * n + 3], 65504.0f);
}

// A half term may come already rounded (CV_16F, half_samples::to_half): every writer stores
// exactly the samples it would have stored from the floats, in the same bytes.
TEST(WriteOutputs, HalfTermsGivenInHalfStoreTheBitsOfTheirFloats) {
  ScratchDir dir;
  const int w = 53, h = 37;  // a partial last zip block
  const Camera cam = Camera::from_fov_x(w, h, 60.0f);
  cv::Mat ao(h, w, CV_32FC1), colour(h, w, CV_32FC3);
  cv::RNG rng(11);
  rng.fill(ao, cv::RNG::UNIFORM, 0.0f, 1.0f);
  rng.fill(colour, cv::RNG::NORMAL, 0.3f, 1.5f);
  colour.at<cv::Vec3f>(3, 4)[0] = 1e6f;     // beyond half: saturates at 65504
  colour.at<cv::Vec3f>(9, 10)[2] = 1e-6f;   // a subnormal half
  cv::Mat colour_half(h, w, CV_16FC3);
  for (int y = 0; y < h; ++y)
    half_samples::to_half(colour.ptr<float>(y), w * 3, colour_half.ptr<uint16_t>(y));
  const std::vector<std::string> names = {"ao", "bent_normal.X", "bent_normal.Y", "bent_normal.Z"};
  const auto read_file = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  for (const char* compression : {"zip", "zips", "none", "piz"}) {
    WriteOptions o;
    o.compression = compression;
    o.threads = 2;
    std::vector<float> stored[2];
    std::string bytes[2];
    for (int given_half = 0; given_half < 2; ++given_half) {
      const cv::Mat& normal = given_half ? colour_half : colour;
      const fs::path path = dir / (std::string(compression) + std::to_string(given_half) + ".exr");
      ASSERT_EQ(write_outputs(path.string(), {{"ao", ao, SampleType::float32}, {"bent_normal", normal, SampleType::half, true}},
                              cam, o),
                "")
          << compression;
      stored[given_half] = read_channels_oiio(path, names);
      bytes[given_half] = read_file(path);
    }
    ASSERT_EQ(stored[0].size(), size_t(w) * h * names.size()) << compression;
    EXPECT_EQ(stored[1], stored[0]) << compression;
    EXPECT_EQ(bytes[1], bytes[0]) << compression;
    EXPECT_EQ(stored[1][(size_t(3) * w + 4) * 4 + 1], 65504.0f) << compression;
    EXPECT_EQ(stored[1][(size_t(20) * w + 21) * 4 + 3], float(half(colour.at<cv::Vec3f>(20, 21)[2]))) << compression;
  }
  // Half samples are only taken for half terms: a float term cannot be stored from them.
  const std::string e = write_outputs((dir / "float.exr").string(),
                                      {{"bent_normal", colour_half, SampleType::float32, true}}, cam);
  EXPECT_NE(e.find("CV_16F only for half terms"), std::string::npos) << e;
}

// The libdeflate encoder writes the header and chunks itself: files must carry the same
// attributes and decode to the same samples as OpenEXR's writer's, for every kind of term,
// both chunk heights, heights that leave a partial last chunk, and any thread count.
TEST(WriteOutputs, ChunkEncodersWriteTheSameHeaderAndSamples) {
  ScratchDir dir;
  const int w = 53, h = 37;  // 37 = 2 x 16 + 5: a partial last zip chunk
  const Camera cam = test_camera(w, h);
  cv::Mat colour = ramp(w, h, 3, 0.013f, -0.2f);
  cv::RNG rng(11);
  cv::Mat noisy(h, w, CV_32FC1);
  rng.fill(noisy, cv::RNG::NORMAL, 0.0f, 3.0f);
  // Half conversion corner cases: ties round to even, subnormals, overflow, NaN.
  colour.at<cv::Vec3f>(1, 2) = {1.0f + 0x1p-11f, 1.0f + 3 * 0x1p-11f, 1e-6f};
  colour.at<cv::Vec3f>(3, 4) = {1e6f, -1e6f, std::numeric_limits<float>::quiet_NaN()};
  colour.at<cv::Vec3f>(5, 6) = {65519.0f, 65520.0f, -0.0f};
  // A signalling NaN and a negative NaN with a payload: Imath keeps bits a hardware
  // conversion may change.
  colour.at<cv::Vec3f>(7, 8) = {std::bit_cast<float>(0x7f800001u), std::bit_cast<float>(0xffc12345u), 6e-8f};
  const std::vector<OutputTerm> terms = {
      {"ao", noisy, SampleType::float32},
      {"confidence", ramp(w, h, 1, 1.0f / 2000.0f, 0.0f), SampleType::half},
      {"bent_normal", ramp(w, h, 3, -0.0005f, 0.9f), SampleType::float32, true},
      {"ssdo_direct", colour, SampleType::half},
      {"composite", colour, SampleType::float32},
      {"bent_normal_half", colour, SampleType::half, true},
  };
  for (const char* compression : {"zip", "zips", "none"})
    for (int threads : {1, 2, 0}) {
      WriteOptions o;
      o.compression = compression;
      o.threads = threads;
      expect_encoders_agree(dir.path, std::string(compression) + "-" + std::to_string(threads), terms, cam, o);
    }
  // A level other than the default, and a frame shorter than one chunk.
  WriteOptions o;
  o.zip_level = 6;
  expect_encoders_agree(dir.path, "zip6", terms, cam, o);
  const Camera small = test_camera(w, 7);
  std::vector<OutputTerm> short_terms;
  for (const auto& t : terms) short_terms.push_back({t.name, t.image.rowRange(0, 7), t.type, t.vector});
  expect_encoders_agree(dir.path, "short", short_terms, small, WriteOptions{});
  // No camera clip distances: no clipNear / clipFar attributes, as OpenEXR's writer does.
  Camera no_clip = cam;
  no_clip.near_view = no_clip.far_view = 0.0f;
  expect_encoders_agree(dir.path, "noclip", {terms[0]}, no_clip, o);
  // Channel names beyond 31 bytes: the long-names flag of the version field.
  expect_encoders_agree(dir.path, "long", {{"ssdo_indirect_denoised_with_a_long_name", colour}}, cam, o);
  // A crop's and an overscan frame's windows (the grid away from the display's origin).
  WriteOptions crop = o;
  crop.data_x = 100, crop.data_y = 80;
  crop.display_window = PixelBox{0, 0, 639, 359};
  expect_encoders_agree(dir.path, "crop", terms, cam, crop);
  WriteOptions overscan = o;
  overscan.data_x = -5, overscan.data_y = -3;
  overscan.display_window = PixelBox{0, 0, w - 11, h - 7};
  expect_encoders_agree(dir.path, "overscan", terms, cam, overscan);
  // The values themselves (the reference is OpenEXR's writer).
  const auto back = read_channels_oiio(dir / "zip-2.libdeflate.exr", {"ssdo_direct.R", "ssdo_direct.G"});
  ASSERT_EQ(back.size(), size_t(w) * h * 2);
  EXPECT_EQ(back[(size_t(1) * w + 2) * 2], 1.0f);
  EXPECT_EQ(back[(size_t(1) * w + 2) * 2 + 1], 1.0f + 0x1p-9f);
  EXPECT_EQ(files_in(dir.path), 2u * (9 + 6));
}

// A crop keeps its place: the output's data and display windows are the frame's, and the
// header camera read back over them (as the reader re-targets it) is the grid's camera.
TEST(WriteOutputs, ACropKeepsItsWindowsAndItsCamera) {
  ScratchDir dir;
  const PixelBox display{0, 0, 639, 359}, data{100, 80, 299, 229};
  Camera full = test_camera(640, 360);
  Camera crop = full;
  crop.view_to_clip = projection_for_data_window(full.view_to_clip, display, data);
  crop.width_px = 200, crop.height_px = 150;
  for (const ChunkEncoder encoder : {ChunkEncoder::own, ChunkEncoder::openexr}) {
    WriteOptions o;
    o.chunk_encoder = encoder;
    o.data_x = data.min_x, o.data_y = data.min_y;
    o.display_window = display;
    const fs::path path = dir / (encoder == ChunkEncoder::own ? "own.exr" : "openexr.exr");
    ASSERT_EQ(write_outputs(path.string(), {{"ao", ramp(200, 150, 1, 1e-5f, 0.0f)}}, crop, o), "");
    Imf::InputFile in(path.c_str());
    const Imath::Box2i dw = in.header().dataWindow(), dsw = in.header().displayWindow();
    EXPECT_EQ(PixelBox({dw.min.x, dw.min.y, dw.max.x, dw.max.y}), data);
    EXPECT_EQ(PixelBox({dsw.min.x, dsw.min.y, dsw.max.x, dsw.max.y}), display);
    ExrCameraMatrices m;
    const auto* w2c = in.header().findTypedAttribute<Imf::M44fAttribute>("worldToCamera");
    const auto* w2n = in.header().findTypedAttribute<Imf::M44fAttribute>("worldToNDC");
    ASSERT_TRUE(w2c && w2n);
    std::memcpy(&m.world_to_camera[0][0], &w2c->value().x[0][0], 64);
    std::memcpy(&m.world_to_ndc[0][0], &w2n->value().x[0][0], 64);
    std::string error, note;
    const auto back = camera_from_exr_matrices(m, display, data, crop.near_view, crop.far_view, &error, &note);
    ASSERT_TRUE(back) << error;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 2; ++r) EXPECT_NEAR(back->view_to_clip[c][r], crop.view_to_clip[c][r], 1e-5f) << c << r;
    // The first sample is the crop's first pixel.
    EXPECT_EQ(read_channels_oiio(path, {"ao"})[0], 0.0f);
  }
}

// A chunk deflate cannot shrink is stored uncompressed (the format's rule); a frame whose
// first rows are flat and whose others are random bits has both kinds of chunks. Many short
// chunks (zips) also span several batches of compression.
TEST(WriteOutputs, IncompressibleChunksAreStoredUncompressed) {
  ScratchDir dir;
  const int w = 24, h = 300;
  const Camera cam = Camera::from_fov_x(w, h, 60.0f, 0.1f, 100.0f);
  cv::Mat noise = random_bits(w, h, 1, 5), noise3 = random_bits(w, h, 3, 6);
  noise.rowRange(0, 40).setTo(0.25f);
  noise3.rowRange(0, 40).setTo(cv::Scalar(0.5f, 0.25f, 1.0f));
  const std::vector<OutputTerm> terms = {{"noise", noise, SampleType::float32},
                                         {"noise3", noise3, SampleType::float32}};
  for (const char* compression : {"zip", "zips"})
    for (int threads : {1, 2}) {
      WriteOptions o;
      o.compression = compression;
      o.threads = threads;
      const std::string name = std::string(compression) + "-" + std::to_string(threads);
      expect_encoders_agree(dir.path, name, terms, cam, o);
      const auto [raw, compressed] = raw_and_compressed_chunks(dir / (name + ".libdeflate.exr"));
      const int lines = std::string(compression) == "zip" ? 16 : 1;
      EXPECT_EQ(raw + compressed, (h + lines - 1) / lines) << name;
      EXPECT_GT(raw, 0) << name;
      EXPECT_GE(compressed, 40 / lines) << name;
      // OpenEXR's writer stores the same chunks raw.
      EXPECT_EQ(raw_and_compressed_chunks(dir / (name + ".openexr.exr")).first, raw) << name;
    }
  // The bits come back exactly.
  const auto back = read_channels_oiio(dir / "zips-2.libdeflate.exr", {"noise"});
  ASSERT_EQ(back.size(), size_t(w) * h);
  EXPECT_EQ(std::memcmp(back.data(), noise.ptr<float>(), back.size() * sizeof(float)), 0);
}

TEST(WriteOutputs, ZipLevelIsCheckedAndRecorded) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(16, 8, 60.0f);
  WriteOptions o;
  EXPECT_EQ(o.zip_level, 1);  // the default: the fast deflate level
  EXPECT_EQ(o.chunk_encoder, ChunkEncoder::own);
  // One range for both encoders (libdeflate alone would take 10 to 12).
  for (const ChunkEncoder encoder : {ChunkEncoder::own, ChunkEncoder::openexr}) {
    o.chunk_encoder = encoder;
    o.zip_level = 0;
    std::string e = write_outputs((dir / "z0.exr").string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam, o);
    EXPECT_NE(e.find("zip level 0"), std::string::npos) << e;
    o.zip_level = 10;
    e = write_outputs((dir / "z10.exr").string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam, o);
    EXPECT_NE(e.find("zip level 10"), std::string::npos) << e;
    EXPECT_FALSE(fs::exists(dir / "z10.exr"));
  }
}

TEST(WriteOutputs, InvalidTermsAreRefused) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(16, 8, 60.0f);
  const std::string p = (dir / "x.exr").string();
  EXPECT_NE(write_outputs(p, {}, cam), "");
  EXPECT_NE(write_outputs(p, {{"ao", cv::Mat(8, 16, CV_8UC1)}}, cam).find("CV_32FC1"), std::string::npos);
  EXPECT_NE(write_outputs(p, {{"ao", ramp(16, 8, 1, 1, 0)}, {"ao", ramp(16, 8, 1, 1, 0)}}, cam).find("twice"),
            std::string::npos);
  EXPECT_NE(write_outputs(p, {{"a", ramp(16, 8, 1, 1, 0)}, {"b", ramp(8, 8, 1, 1, 0)}}, cam), "");
  EXPECT_NE(write_outputs(p, {{"a", ramp(20, 8, 1, 1, 0)}}, cam).find("camera grid"), std::string::npos);
  EXPECT_EQ(files_in(dir.path), 0u);
}

TEST(WriteOutputs, FailureLeavesNoTempFileAndTheFinalNameUntouched) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(16, 8, 60.0f);
  // The final name is taken by a folder: the rename fails after the EXR was written.
  const fs::path target = dir / "taken.exr";
  fs::create_directories(target / "inside");
  const std::string e = write_outputs(target.string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam);
  EXPECT_NE(e, "");
  EXPECT_NE(e.find(target.string()), std::string::npos) << e;
  EXPECT_TRUE(fs::is_directory(target / "inside"));
  EXPECT_EQ(files_in(dir.path), 1u);  // only the folder: the temp file was removed
  // A folder that does not exist.
  EXPECT_NE(write_outputs((dir / "no" / "such" / "out.exr").string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam)
                .find("folder does not exist"),
            std::string::npos);
  // An existing output is replaced whole on success.
  const fs::path out = dir / "out.exr";
  std::ofstream(out) << "old";
  EXPECT_EQ(write_outputs(out.string(), {{"ao", ramp(16, 8, 1, 0.01f, 0.0f)}}, cam), "");
  EXPECT_EQ(channel_names(out), std::vector<std::string>{"ao"});
}

// The EXR is renamed into place after its previews: a preview that cannot be written
// leaves no EXR (a rerun, which skips frames whose EXR is up to date, computes it again)
// and no temp file.
TEST(WriteOutputs, APreviewThatCannotBeWrittenLeavesNoExr) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(4, 2, 60.0f);
  WriteOptions o;
  o.png_previews = true;
  fs::create_directories(dir / "frame.bent_normal.png");  // a folder where the preview goes
  const std::string error = write_outputs(
      (dir / "frame.exr").string(),
      {{"ao", cv::Mat(2, 4, CV_32FC1, cv::Scalar(0.5f))},
       {"bent_normal", cv::Mat(2, 4, CV_32FC3, cv::Scalar(0.0f, 0.0f, 1.0f)), SampleType::half, true}},
      cam, o);
  EXPECT_NE(error.find("frame.bent_normal.png"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir / "frame.exr"));
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

TEST(WriteOutputs, PngPreviewsAreSrgbClampedEightBit) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(4, 2, 60.0f);
  cv::Mat ao(2, 4, CV_32FC1, cv::Scalar(0.5f));
  ao.at<float>(0, 1) = 2.0f;   // clamped to 1
  ao.at<float>(0, 2) = -1.0f;  // clamped to 0
  ao.at<float>(0, 3) = 0.0021973f;  // linear segment: 12.92 v
  cv::Mat normal(2, 4, CV_32FC3, cv::Scalar(0.0f, 0.0f, 1.0f));
  WriteOptions o;
  o.png_previews = true;
  ASSERT_EQ(write_outputs((dir / "frame.exr").string(),
                          {{"ao", ao}, {"bent_normal", normal, SampleType::half, true}}, cam, o),
            "");
  ASSERT_TRUE(fs::exists(dir / "frame.ao.png"));
  ASSERT_TRUE(fs::exists(dir / "frame.bent_normal.png"));
  EXPECT_EQ(files_in(dir.path), 3u);
  auto in = OIIO::ImageInput::open((dir / "frame.ao.png").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().nchannels, 1);
  EXPECT_EQ(in->spec().format, OIIO::TypeDesc::UINT8);
  std::vector<uint8_t> px(8);
  ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::UINT8, px.data()));
  EXPECT_EQ(px[0], 188);  // sRGB(0.5) = 0.7354 -> 188
  EXPECT_EQ(px[1], 255);
  EXPECT_EQ(px[2], 0);
  EXPECT_EQ(px[3], 7);  // 12.92 * 0.0021973 * 255 = 7.24
  auto nin = OIIO::ImageInput::open((dir / "frame.bent_normal.png").string());
  ASSERT_TRUE(nin);
  std::vector<uint8_t> npx(24);
  ASSERT_TRUE(nin->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, npx.data()));
  EXPECT_EQ(npx[0], 128);  // 0.5 * 0 + 0.5
  EXPECT_EQ(npx[2], 255);  // 0.5 * 1 + 0.5
}

// A file named after one of its terms (eval's heatmap NAME.error.exr) names that term's
// preview NAME.error.png, not NAME.error.error.png; the other terms keep NAME.error.<term>.png.
TEST(WriteOutputs, ThePreviewOfTheTermAFileIsNamedAfterTakesTheFilesName) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(4, 2, 60.0f);
  const cv::Mat error(2, 4, CV_32FC3, cv::Scalar(1.0f, 0.0f, 0.0f)), ao(2, 4, CV_32FC1, cv::Scalar(0.5f));
  WriteOptions o;
  o.png_previews = true;
  ASSERT_EQ(write_outputs((dir / "a.error.exr").string(), {{"error", error}, {"ao", ao}}, cam, o), "");
  EXPECT_EQ(files_in(dir.path), 3u);
  EXPECT_FALSE(fs::exists(dir / "a.error.error.png"));
  EXPECT_TRUE(fs::exists(dir / "a.error.ao.png"));
  auto in = OIIO::ImageInput::open((dir / "a.error.png").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().nchannels, 3);
  std::vector<uint8_t> px(24);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px.data()));
  EXPECT_EQ(px[0], 255);  // the error term's red
  EXPECT_EQ(px[1], 0);
}

// Every user of the previews' names (the writer, the rerun check, the clean-up) names them
// through preview_path.
TEST(WriteOutputs, PreviewPathsAreNamedAfterTheTermUnlessTheFileIs) {
  EXPECT_EQ(preview_path("out/a.ssdo.exr", "ao"), "out/a.ssdo.ao.png");
  EXPECT_EQ(preview_path("out/a.error.exr", "error"), "out/a.error.png");
  EXPECT_EQ(preview_path("out/a.error.exr", "ao"), "out/a.error.ao.png");
  EXPECT_EQ(preview_path("out/ao.exr", "ao"), "out/ao.ao.png");  // a stem that is only the term
  EXPECT_EQ(preview_path("out/a.bent_normal.exr", "normal"), "out/a.bent_normal.normal.png");
}

// The sRGB encoding of previews equals the transfer function rounded to 8 bits (in float,
// as IEC 61966-2-1 writes it) on both sides of every step between two bytes and across
// [0, 1], and maps what is not a number to 0.
TEST(WriteOutputs, PngPreviewBytesAreTheRoundedTransferFunctionAtEveryStep) {
  const auto encode = [](float v) {
    if (!std::isfinite(v)) v = 0.0f;
    v = std::clamp(v, 0.0f, 1.0f);
    const float e = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
    return int(std::lround(e * 255.0f));
  };
  std::vector<float> values = {std::nanf(""), std::numeric_limits<float>::infinity(),
                               -std::numeric_limits<float>::infinity(), -0.0f, 0.0f, 1.0f, 1.5f};
  for (int k = 1; k < 256; ++k) {
    const double e = (k - 0.5) / 255.0;  // the encoded value where the byte steps to k
    const double linear = e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
    const float at = float(linear);
    for (const float v : {std::nextafter(std::nextafter(at, 0.0f), 0.0f), std::nextafter(at, 0.0f), at,
                          std::nextafter(at, 2.0f), std::nextafter(std::nextafter(at, 2.0f), 2.0f)})
      values.push_back(v);
  }
  // And floats spread over [0, 1] by their bit patterns (every ulp scale from 1e-38 up).
  for (uint32_t bits = 0; bits <= std::bit_cast<uint32_t>(1.0f); bits += 9973) values.push_back(std::bit_cast<float>(bits));
  const cv::Mat ao(1, int(values.size()), CV_32FC1, values.data());
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(ao.cols, 1, 60.0f);
  WriteOptions o;
  o.png_previews = true;
  o.threads = 2;
  // Three terms, so that previews are written side by side.
  ASSERT_EQ(write_outputs((dir / "steps.exr").string(), {{"a", ao}, {"b", ao.clone()}, {"c", ao.clone()}}, cam, o),
            "");
  for (const char* term : {"a", "b", "c"}) {
    auto in = OIIO::ImageInput::open((dir / (std::string("steps.") + term + ".png")).string());
    ASSERT_TRUE(in) << term;
    std::vector<uint8_t> px(values.size());
    ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::UINT8, px.data()));
    int steps_seen = 0;
    for (size_t i = 0; i < values.size(); ++i) {
      ASSERT_EQ(int(px[i]), encode(values[i])) << term << " at " << values[i];
      steps_seen += i > 7 && i < 7 + 5 * 255 && px[i] != px[i - 1];
    }
    EXPECT_GE(steps_seen, 250) << term;  // the values straddle (almost) every step
  }
}

}  // namespace
}  // namespace ssdo::test
