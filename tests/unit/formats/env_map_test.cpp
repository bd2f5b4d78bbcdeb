// Environment maps: EXR through OpenEXR, other formats through the OpenImageIO module; the
// same pixels either way, and clean errors.
#include "formats/env_map.h"

#include <fstream>
#include <limits>

#include <gtest/gtest.h>

#include "formats/oiio_module.h"
#include "tests/unit/formats/formats_test_util.h"

namespace ssdo {
namespace {

using test::ScratchDir;
using test::TestChannel;
using test::TestExr;

TestExr rgb_map(int w, int h) {
  TestExr exr;
  exr.width = w;
  exr.height = h;
  exr.data_x = 3;  // a data window off the origin must not shift the pixels
  exr.data_y = -2;
  TestChannel r{"R", OIIO::TypeDesc::HALF, {}}, g{"G", OIIO::TypeDesc::FLOAT, {}},
      b{"B", OIIO::TypeDesc::HALF, {}};
  for (int i = 0; i < w * h; ++i) {
    r.values.push_back(float(i % 17) * 0.5f);
    g.values.push_back(float(i) * 0.25f);
    b.values.push_back(i == 5 ? -1.0f : 2.0f);  // negative radiance is clamped to 0
    if (i == 6) g.values.back() = 3e38f;        // beyond kMaxEnvRadiance: clamped to it
  }
  exr.channels = {b, g, r};
  return exr;
}

TEST(EnvMap, ExrRgbIsReadInPlaceWithNegativesClamped) {
  ScratchDir dir;
  const int w = 8, h = 4;
  const TestExr exr = rgb_map(w, h);
  ASSERT_TRUE(exr.write(dir / "env.exr"));
  const EnvMapResult env = read_env_map((dir / "env.exr").string());
  ASSERT_TRUE(env.ok()) << env.error;
  ASSERT_EQ(env.radiance_rgb.type(), CV_32FC3);
  ASSERT_EQ(env.radiance_rgb.cols, w);
  ASSERT_EQ(env.radiance_rgb.rows, h);
  for (int i = 0; i < w * h; ++i) {
    const cv::Vec3f p = env.radiance_rgb.at<cv::Vec3f>(i / w, i % w);
    EXPECT_EQ(p[0], float(i % 17) * 0.5f) << i;
    EXPECT_EQ(p[1], i == 6 ? kMaxEnvRadiance : float(i) * 0.25f) << i;
    EXPECT_EQ(p[2], i == 5 ? 0.0f : 2.0f) << i;
  }
  EXPECT_FALSE(oiio_module::loaded()) << "an EXR map must not need OpenImageIO";
}

// ZIP, ZIPS and uncompressed maps go through the G-buffer reader's decoder, the others
// through OpenEXR: the same floats (half and float channels, a data window off the origin,
// more than one chunk of lines).
TEST(EnvMap, EveryCompressionGivesTheSameMap) {
  ScratchDir dir;
  TestExr exr = rgb_map(42, 21);
  cv::Mat reference;
  for (const char* compression : {"piz", "zip", "zips", "none", "rle"}) {
    exr.compression = compression;
    const std::string path = (dir / (std::string(compression) + ".exr")).string();
    ASSERT_TRUE(exr.write(path));
    const EnvMapResult env = read_env_map(path);
    ASSERT_TRUE(env.ok()) << compression << ": " << env.error;
    if (reference.empty()) {
      reference = env.radiance_rgb;
      EXPECT_EQ(reference.at<cv::Vec3f>(2, 3), cv::Vec3f(float(87 % 17) * 0.5f, 87 * 0.25f, 2.0f));
      continue;
    }
    EXPECT_EQ(cv::norm(env.radiance_rgb, reference, cv::NORM_INF), 0.0) << compression;
  }
}

TEST(EnvMap, ExrLuminanceIsReplicated) {
  ScratchDir dir;
  TestExr exr;
  exr.width = 4;
  exr.height = 2;
  exr.channels = {{"Y", OIIO::TypeDesc::FLOAT, {0, 1, 2, 3, 4, 5, 6, 7}}};
  ASSERT_TRUE(exr.write(dir / "y.exr"));
  const EnvMapResult env = read_env_map((dir / "y.exr").string());
  ASSERT_TRUE(env.ok()) << env.error;
  EXPECT_EQ(env.radiance_rgb.at<cv::Vec3f>(1, 2), cv::Vec3f(6, 6, 6));
}

TEST(EnvMap, OtherFormatsGoThroughTheModuleWithTheSamePixels) {
  ScratchDir dir;
  // Radiance HDR holds shared-exponent RGB: values that are exact in it.
  const int w = 6, h = 3;
  cv::Mat pixels(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) pixels.at<cv::Vec3f>(y, x) = cv::Vec3f(float(x), 0.5f, float(y) * 2);
  auto out = OIIO::ImageOutput::create("hdr");
  ASSERT_TRUE(out);
  ASSERT_TRUE(out->open((dir / "env.hdr").string(), OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT)));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels.data));
  ASSERT_TRUE(out->close());
  const EnvMapResult env = read_env_map((dir / "env.hdr").string());
  ASSERT_TRUE(env.ok()) << env.error;
  EXPECT_TRUE(oiio_module::loaded());
  EXPECT_EQ(cv::norm(env.radiance_rgb, pixels, cv::NORM_INF), 0.0);

  // The check of another format reads its header only: a map whose pixels are cut off
  // passes it (the reader fails on it), one whose header declares too many pixels does not.
  const auto bytes = std::filesystem::file_size(dir / "env.hdr");
  std::filesystem::copy_file(dir / "env.hdr", dir / "cut.hdr");
  std::filesystem::resize_file(dir / "cut.hdr", bytes - 20);
  EXPECT_EQ(check_env_map((dir / "cut.hdr").string()), "");
  EXPECT_FALSE(read_env_map((dir / "cut.hdr").string()).ok());
  const std::string over = check_env_map((dir / "env.hdr").string(), w * h - 1);
  EXPECT_NE(over.find("environment map " + (dir / "env.hdr").string() + ": image size 6 x 3"), std::string::npos)
      << over;
}

// The map is its display window, the whole sphere: a data window covering part of it (a
// map cropped to its bright half) is placed in it, black elsewhere; one reaching past it
// (overscan) is cut to it.
TEST(EnvMap, TheDataWindowIsPlacedInTheDisplayWindow) {
  ScratchDir dir;
  TestExr exr;
  exr.width = 4;
  exr.height = 4;
  exr.data_x = 4;  // the right half of an 8 x 4 sphere
  exr.display_x = 0, exr.display_y = 0, exr.display_width = 8, exr.display_height = 4;
  exr.channels = {{"Y", OIIO::TypeDesc::FLOAT, std::vector<float>(16, 2.0f)}};
  ASSERT_TRUE(exr.write(dir / "half.exr"));
  const EnvMapResult env = read_env_map((dir / "half.exr").string());
  ASSERT_TRUE(env.ok()) << env.error;
  ASSERT_EQ(env.radiance_rgb.size(), cv::Size(8, 4));
  EXPECT_EQ(env.radiance_rgb.at<cv::Vec3f>(1, 3), cv::Vec3f(0, 0, 0));
  EXPECT_EQ(env.radiance_rgb.at<cv::Vec3f>(1, 4), cv::Vec3f(2, 2, 2));
  EXPECT_EQ(cv::sum(env.radiance_rgb)[0], 2.0 * 16);
  exr.data_x = -2, exr.data_y = -1;  // overscan: 2 columns and 1 row outside
  exr.display_width = 4, exr.display_height = 2;
  std::vector<float>& v = exr.channels[0].values;
  for (int i = 0; i < 16; ++i) v[size_t(i)] = float(i);
  ASSERT_TRUE(exr.write(dir / "over.exr"));
  const EnvMapResult over = read_env_map((dir / "over.exr").string());
  ASSERT_TRUE(over.ok()) << over.error;
  ASSERT_EQ(over.radiance_rgb.size(), cv::Size(4, 2));
  EXPECT_EQ(over.radiance_rgb.at<cv::Vec3f>(0, 0)[0], 6.0f);  // data (2, 1) = value 1 * 4 + 2
  EXPECT_EQ(over.radiance_rgb.at<cv::Vec3f>(1, 1)[0], 11.0f);
  EXPECT_EQ(over.radiance_rgb.at<cv::Vec3f>(1, 3)[0], 0.0f);  // right of the data window
}

// An equirectangular map is 2:1 (360 x 180 degrees); a square mirror ball or a 4:3 cube
// cross read as one would light from the wrong directions: refused by name, before the
// pixels are decoded, in EXR (its display window) and in other formats alike. A pixel or
// 5% off 2:1 is an export's rounding: read.
TEST(EnvMap, MapsThatAreNot2To1AreRefused) {
  ScratchDir dir;
  auto y_map = [&](int w, int h, const std::string& name) {
    TestExr exr;
    exr.width = w;
    exr.height = h;
    exr.channels = {{"Y", OIIO::TypeDesc::FLOAT, std::vector<float>(size_t(w * h), 1.0f)}};
    EXPECT_TRUE(exr.write(dir / name));
    return (dir / name).string();
  };
  for (const auto& [w, h] : {std::pair{16, 16}, {16, 12}, {12, 16}, {48, 8}, {44, 20}}) {
    const std::string path = y_map(w, h, "map" + std::to_string(w) + "x" + std::to_string(h) + ".exr");
    const EnvMapResult r = read_env_map(path);
    EXPECT_FALSE(r.ok()) << w << " x " << h;
    EXPECT_NE(r.error.find(path + ": the environment map is " + std::to_string(w) + " x " + std::to_string(h) +
                           ", not 2:1"),
              std::string::npos)
        << r.error;
    EXPECT_EQ(check_env_map(path), r.error);
  }
  for (const auto& [w, h] : {std::pair{41, 20}, {42, 20}, {39, 20}, {3, 1}, {2, 1}}) {
    const EnvMapResult r = read_env_map(y_map(w, h, "ok" + std::to_string(w) + "x" + std::to_string(h) + ".exr"));
    EXPECT_TRUE(r.ok()) << w << " x " << h << ": " << r.error;
    EXPECT_EQ(r.radiance_rgb.size(), cv::Size(w, h));
  }
  // Another format: refused by its header alone, and after a decode.
  {
    auto out = OIIO::ImageOutput::create("png");
    ASSERT_TRUE(out);
    const std::string png = (dir / "ball.png").string();
    ASSERT_TRUE(out->open(png, OIIO::ImageSpec(8, 8, 3, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, cv::Mat(8, 8, CV_8UC3, cv::Scalar::all(100)).data));
    out->close();
    const EnvMapResult r = read_env_map(png);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.error.find(png + ": the environment map is 8 x 8, not 2:1"), std::string::npos) << r.error;
    EXPECT_EQ(check_env_map(png), r.error);
  }
}

// An 8-bit PNG holds sRGB-encoded values: decoded to linear radiance (code 128 is 0.216,
// not 0.502); a map whose every value is NaN, infinite or negative is refused, not read as
// a black sky; a two-channel image is refused by its header check already.
TEST(EnvMap, DisplayEncodedMapsAreDecodedAndMapsWithoutLightRefused) {
  ScratchDir dir;
  {
    cv::Mat grey(2, 4, CV_8UC3, cv::Scalar::all(128));
    auto out = OIIO::ImageOutput::create("png");
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open((dir / "grey.png").string(), OIIO::ImageSpec(4, 2, 3, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, grey.data));
    ASSERT_TRUE(out->close());
    cv::Mat la(2, 4, CV_8UC2, cv::Scalar::all(200));
    out = OIIO::ImageOutput::create("png");
    ASSERT_TRUE(out->open((dir / "la.png").string(), OIIO::ImageSpec(4, 2, 2, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, la.data));
    ASSERT_TRUE(out->close());
  }
  const EnvMapResult grey = read_env_map((dir / "grey.png").string());
  ASSERT_TRUE(grey.ok()) << grey.error;
  EXPECT_NEAR(grey.radiance_rgb.at<cv::Vec3f>(1, 2)[1], 0.2158605, 1e-5);
  const std::string la = check_env_map((dir / "la.png").string());
  EXPECT_NE(la.find("la.png: the environment map has 2 channels"), std::string::npos) << la;
  TestExr bad;
  bad.width = 2;
  bad.height = 1;
  bad.channels = {{"Y", OIIO::TypeDesc::FLOAT, {std::numeric_limits<float>::quiet_NaN(), -1.0f}}};
  ASSERT_TRUE(bad.write(dir / "nan.exr"));
  const EnvMapResult nan = read_env_map((dir / "nan.exr").string());
  EXPECT_FALSE(nan.ok());
  EXPECT_NE(nan.error.find("nan.exr: every value of the environment map is NaN, infinite or negative"),
            std::string::npos)
      << nan.error;
  bad.channels = {{"Y", OIIO::TypeDesc::FLOAT, {0.0f, 0.0f}}};  // a black sky is a sky
  ASSERT_TRUE(bad.write(dir / "black.exr"));
  EXPECT_TRUE(read_env_map((dir / "black.exr").string()).ok());
}

TEST(EnvMap, ErrorsNameTheFile) {
  ScratchDir dir;
  const EnvMapResult missing = read_env_map((dir / "none.exr").string());
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.error.find("none.exr"), std::string::npos) << missing.error;
  std::ofstream(dir / "text.exr") << "not an image";
  const EnvMapResult text = read_env_map((dir / "text.exr").string());
  EXPECT_FALSE(text.ok());
  EXPECT_NE(text.error.find("text.exr"), std::string::npos) << text.error;
  TestExr exr;
  exr.width = 2;
  exr.height = 1;
  exr.channels = {{"Z", OIIO::TypeDesc::FLOAT, {1, 2}}};
  ASSERT_TRUE(exr.write(dir / "depth.exr"));
  const EnvMapResult depth = read_env_map((dir / "depth.exr").string());
  EXPECT_FALSE(depth.ok());
  EXPECT_NE(depth.error.find("needs channels R, G and B, or Y (it has Z)"), std::string::npos) << depth.error;
  // A multi-part map is read from its first part, and the message says so.
  TestExr first = exr, second = rgb_map(2, 1);
  first.part_name = "depth";
  second.part_name = "rgb";
  second.data_x = second.data_y = 0;
  ASSERT_TRUE(test::write_parts(dir / "parts.exr", {first, second}));
  const EnvMapResult parts = read_env_map((dir / "parts.exr").string());
  EXPECT_FALSE(parts.ok());
  EXPECT_NE(parts.error.find("(it has Z) in its first part; the map is read from the first of its 2 parts"),
            std::string::npos)
      << parts.error;
  const TestExr big = rgb_map(8, 4);
  ASSERT_TRUE(big.write(dir / "big.exr"));
  const EnvMapResult over = read_env_map((dir / "big.exr").string(), 31);
  EXPECT_FALSE(over.ok());
  EXPECT_NE(over.error.find("big.exr"), std::string::npos) << over.error;

  // The check without the pixels refuses each of them with read_env_map's error, and
  // passes the map within the limit.
  EXPECT_EQ(check_env_map((dir / "none.exr").string()), missing.error);
  EXPECT_EQ(check_env_map((dir / "text.exr").string()), text.error);
  EXPECT_EQ(check_env_map((dir / "depth.exr").string()), depth.error);
  EXPECT_EQ(check_env_map((dir / "big.exr").string(), 31), over.error);
  EXPECT_EQ(check_env_map((dir / "big.exr").string(), 128), "");
}

}  // namespace
}  // namespace ssdo
