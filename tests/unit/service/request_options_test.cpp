#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "service/request_options.h"

namespace ssdo {
namespace {

using json = nlohmann::json;

TEST(FrameOptions, EveryKeyRoundTripsThroughJson) {
  FrameOptionArgs a;
  a.read.maps = {"depth=Z", "normal=N"};
  a.read.camera_json = "/cams/a.json";
  a.read.fov_x_deg = 50;
  a.read.depth_kind = "radial";
  a.read.part = "depth_left";
  a.compute.method = "hbao";
  a.compute.preset = "high";
  a.compute.radius_world = 0.5f;
  a.compute.thickness_world = 0.25f;
  a.compute.threads = 3;
  a.compute.terms = "ao,ssdo";
  a.compute.ssdo_method = "oracle";
  a.compute.ssdo_preset = "low";
  a.compute.sky = "1,0.2";
  a.compute.env_up = "y";
  a.compute.composite = "ssao";
  a.compression = "piz";
  a.png = true;
  const json j = to_json(a);
  EXPECT_EQ(j.size(), frame_option_keys().size());
  FrameOptionArgs b;
  std::string error;
  ASSERT_TRUE(apply_json(j, b, error)) << error;
  EXPECT_EQ(to_json(b), j);
}

TEST(FrameOptions, KeysAreTheCommandLineFlagNames) {
  for (const std::string& key : frame_option_keys()) {
    EXPECT_EQ(key.find('_'), std::string::npos) << key;  // flags use '-'
    EXPECT_EQ(key.rfind("--", 0), std::string::npos) << key;
  }
  const json j = to_json(FrameOptionArgs{});
  for (const char* key : {"method", "preset", "terms", "env", "ssdo-method", "depth-kind", "map", "png"})
    EXPECT_TRUE(j.contains(key)) << key;
}

TEST(FrameOptions, UnknownKeysAndBadValuesNameTheKey) {
  FrameOptionArgs a;
  std::string error;
  EXPECT_FALSE(apply_json(json{{"methd", "gtao"}}, a, error));
  EXPECT_NE(error.find("methd"), std::string::npos);
  EXPECT_FALSE(apply_json(json{{"method", "magic"}}, a, error));
  EXPECT_NE(error.find("method"), std::string::npos);
  EXPECT_FALSE(apply_json(json{{"preset", 3}}, a, error));
  EXPECT_NE(error.find("preset"), std::string::npos);
  EXPECT_FALSE(apply_json(json{{"radius", -1}}, a, error));
  EXPECT_FALSE(apply_json(json{{"radius", "big"}}, a, error));
  // A radius whose square overflows a float is no radius; 0 is the default's other name.
  EXPECT_FALSE(apply_json(json{{"radius", 1e20}}, a, error));
  EXPECT_EQ(error, "\"radius\" must be 0 (unset) or a number in [1e-09, 1e+12]");
  ASSERT_TRUE(apply_json(json{{"radius", 0}, {"thickness", 0}, {"env-constant", 0}}, a, error)) << error;
  EXPECT_EQ(a.compute.radius_world, 0.0f);
  EXPECT_FALSE(apply_json(json{{"fov", 200}}, a, error));
  EXPECT_FALSE(apply_json(json{{"threads", 1.5}}, a, error));
  EXPECT_FALSE(apply_json(json{{"png", "yes"}}, a, error));
  EXPECT_FALSE(apply_json(json{{"map", {1, 2}}}, a, error));
  EXPECT_FALSE(apply_json(json{{"compression", "lzma"}}, a, error));
  EXPECT_FALSE(apply_json(json::array(), a, error));
  ASSERT_TRUE(apply_json(json{{"map", "depth=Z"}}, a, error)) << error;  // one string = a list of one
  EXPECT_EQ(a.read.maps, std::vector<std::string>{"depth=Z"});
}

// A NUL ends a path for the system: "/ok/cam.json\0/etc/x" would be checked as one file
// and opened as another.
TEST(FrameOptions, TextWithANulByteIsRefused) {
  using namespace std::string_literals;
  FrameOptionArgs a;
  std::string error;
  EXPECT_FALSE(apply_json(json{{"camera", "/ok/cam.json\0/etc/passwd"s}}, a, error));
  EXPECT_EQ(error, "\"camera\" holds a NUL byte");
  EXPECT_TRUE(a.read.camera_json.empty());
  EXPECT_FALSE(apply_json(json{{"env", "/ok/sky.exr\0"s}}, a, error));
  EXPECT_EQ(error, "\"env\" holds a NUL byte");
  EXPECT_FALSE(apply_json(json{{"map", "depth=Z\0"s}}, a, error));
  EXPECT_EQ(error, "\"map\" holds a NUL byte");
  EXPECT_FALSE(apply_json(json{{"map", json::array({"depth=Z", "normal=N\0x"s})}}, a, error));
  EXPECT_EQ(error, "\"map\" holds a NUL byte");
}

TEST(FrameOptions, FlagsGivenOnTheCommandLineWinOverTheConfig) {
  FrameOptionArgs a;
  a.compute.method = "hbao";  // as if given as --method hbao
  std::string error;
  ASSERT_TRUE(apply_json(json{{"method", "gtao"}, {"preset", "high"}}, a, error,
                         [](const std::string& key) { return key == "method"; }))
      << error;
  EXPECT_EQ(a.compute.method, "hbao");
  EXPECT_EQ(a.compute.preset, "high");
}

TEST(FrameOptions, OnlyGivenKeysWhenAsked) {
  FrameOptionArgs a;
  const json j = to_json(a, [](const std::string& key) { return key == "terms" || key == "png"; });
  EXPECT_EQ(j.size(), 2u);
  EXPECT_TRUE(j.contains("terms"));
}

TEST(FrameOptions, ResolvesIntoARequest) {
  FrameOptionArgs a;
  std::string error;
  ASSERT_TRUE(apply_json(json{{"terms", "ao,ssdo"}, {"compression", "none"}, {"png", true}, {"sky", "1,0.2"}}, a, error));
  FrameRequest r;
  ASSERT_TRUE(resolve_frame_options(a, r, error)) << error;
  EXPECT_TRUE(r.terms.ao && r.terms.ssdo && r.terms.composite);  // ssdo brings the composite
  EXPECT_EQ(r.write.compression, "none");
  EXPECT_TRUE(r.write.png_previews);
  EXPECT_TRUE(r.environment != nullptr);
  a.compute.terms = "fog";
  EXPECT_FALSE(resolve_frame_options(a, r, error));
  EXPECT_NE(error.find("fog"), std::string::npos);
}

TEST(FrameOptions, ConfigFileErrorsNameTheFile) {
  const std::string path = (std::filesystem::temp_directory_path() / ("ssdo_cfg_" + std::to_string(::getpid()) + ".json")).string();
  std::ofstream(path) << "{\"method\": \"hbao\",\n \"preset\": }";
  json j;
  std::string error;
  EXPECT_FALSE(load_json_file(path, j, error));
  EXPECT_NE(error.find(path), std::string::npos);
  std::ofstream(path) << "[1]";
  EXPECT_FALSE(load_json_file(path, j, error));
  std::ofstream(path) << R"({"method": "hbao"})";
  EXPECT_TRUE(load_json_file(path, j, error)) << error;
  EXPECT_FALSE(load_json_file(path + ".missing", j, error));
  std::filesystem::remove(path);
}

TEST(FrameOptions, OptionPathsAreTheFilesAServiceMustCheck) {
  FrameOptionArgs a;
  EXPECT_TRUE(option_paths(a).empty());
  a.read.camera_json = "/x/cam.json";
  a.compute.env_path = "/x/env.exr";
  EXPECT_EQ(option_paths(a), (std::vector<std::string>{"/x/cam.json", "/x/env.exr"}));
}

}  // namespace
}  // namespace ssdo
