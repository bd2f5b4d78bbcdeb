// The frame options through the real binary: the generated reference is the one committed,
// and the options that reach kernel capabilities (multi-bounce AO, the guard band of
// overscan frames) change the outputs as they say.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_binary.h"

namespace ssdo::test {
namespace {

namespace fs = std::filesystem;

std::string example(const std::string& name) { return (source_dir() / "examples" / "frames" / name).string(); }

struct Image {
  int width = 0, height = 0;
  std::vector<std::string> channels;
  std::vector<float> pixels;  // interleaved
  float at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels.size() + c]; }
  int channel(const std::string& name) const {
    const auto it = std::find(channels.begin(), channels.end(), name);
    return it == channels.end() ? -1 : int(it - channels.begin());
  }
};

Image read_image(const std::string& path) {
  Image img;
  auto in = OIIO::ImageInput::open(path);
  if (!in) return img;
  const OIIO::ImageSpec& spec = in->spec();
  img.width = spec.width;
  img.height = spec.height;
  img.channels = spec.channelnames;
  img.pixels.resize(size_t(spec.width) * spec.height * spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.pixels.data());
  return img;
}

Image process(const ScratchDir& out, const std::string& name, const std::string& flags) {
  const fs::path dir = out.path / name;
  fs::create_directories(dir);
  const RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + dir.string() + " " + flags);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return read_image((dir / "cornell.ssdo.exr").string());
}

TEST(OptionsCli, ReferenceInDocsIsWhatTheBinaryPrints) {
  const RunResult r = run_ssdo("options --markdown");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(source_dir() / "docs" / "options.md");
  std::stringstream committed;
  committed << in.rdbuf();
  EXPECT_EQ(r.output, committed.str())
      << "docs/options.md is out of date: regenerate it with `ssdo options --markdown > docs/options.md`";
}

// The command line wins over a config: for the environment, one choice of three keys, a
// command-line --env-constant replaces the config's "sky" (it was refused as two
// environments); two in the config itself stay an error.
TEST(OptionsCli, AnEnvironmentOnTheCommandLineReplacesTheConfigs) {
  ScratchDir out;
  const std::string base = "process " + example("cornell.exr") + " -o " + out.path.string() + " --preset low --terms ao,composite";
  std::ofstream(out / "cfg.json") << R"({"sky": "1,0"})";
  RunResult r = run_ssdo(base + " --config " + (out / "cfg.json") + " --env-constant 2");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto in = OIIO::ImageInput::open((out / "cornell.ssdo.exr"));
  ASSERT_TRUE(in);
  const nlohmann::json made = nlohmann::json::parse(in->spec().get_string_attribute("ssdo/options"), nullptr, false);
  in.reset();
  EXPECT_EQ(made.value("sky", "?"), "") << made.dump();
  EXPECT_EQ(made.value("env-constant", 0.0), 2.0) << made.dump();
  std::ofstream(out / "two.json") << R"({"sky": "1,0", "env-constant": 2})";
  r = run_ssdo(base + " --config " + (out / "two.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("give one environment"), std::string::npos) << r.output;
}

// Options that change nothing with the others are said, and --max-error without --quality
// auto does not make outputs stale (it is recorded as its default).
TEST(OptionsCli, OptionsWithoutEffectAreSaidAndDoNotMakeOutputsStale) {
  ScratchDir out;
  const std::string base = "process " + example("cornell.exr") + " -o " + out.path.string() + " --preset low --terms ao";
  RunResult r = run_ssdo(base);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_ssdo(base + " --max-error 0.01 --composite ssao");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("note: --max-error has no effect without --quality auto"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("note: --composite has no effect: --terms ao writes no composite"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
}

TEST(OptionsCli, OutOfRangeValuesAreUsageErrorsOnTheCommandLineAndInAConfig) {
  ScratchDir out;
  const std::string base = "process " + example("cornell.exr") + " -o " + out.path.string();
  RunResult r = run_ssdo(base + " --guard-band -1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("must be an integer in [0, 4096]"), std::string::npos) << r.output;
  // Numbers are decimal: "0x10" (16 to std::stod) is no radius and no sky.
  for (const char* given : {" --radius 0x10", " --sky 0x10,1"}) {
    r = run_ssdo(base + given);
    EXPECT_EQ(r.exit_code, 2) << given << "\n" << r.output;
  }
  std::ofstream(out / "cfg.json") << R"({"guard-band": 5000})";
  r = run_ssdo(base + " --config " + (out / "cfg.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("\"guard-band\" must be an integer in [0, 4096]"), std::string::npos) << r.output;
}

// An empty value on the command line (a script's unset variable) is refused, a frame
// option's naming the default it would have silently given; in a config "" is the default, as the options
// recorded in an output's header have it.
TEST(OptionsCli, AnEmptyTextValueOnTheCommandLineIsRefused) {
  ScratchDir out;
  const std::string base = "process " + example("cornell.exr") + " -o " + out.path.string() + " --preset low";
  for (const char* option : {"--camera", "--env", "--part", "--sky", "--composite"}) {
    const RunResult r = run_ssdo(base + " " + option + " ''");
    EXPECT_EQ(r.exit_code, 2) << option << "\n" << r.output;
    EXPECT_NE(r.output.find(std::string(option) + ": an empty value; leave the option out for the default"),
              std::string::npos)
        << r.output;
    EXPECT_FALSE(fs::exists(out.path / "cornell.ssdo.exr")) << option;
  }
  // So is any other option's: a farm task's --chunk "$TASK" left empty would compute every
  // frame of the range in every task.
  for (const char* option : {"--chunk", "--shot-frames", "--frames", "--out"}) {
    const RunResult r = run_ssdo(base + " " + option + " ''");
    EXPECT_EQ(r.exit_code, 2) << option << "\n" << r.output;
    EXPECT_NE(r.output.find(": an empty value"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out.path / "cornell.ssdo.exr")) << option;
  }
  std::ofstream(out / "cfg.json") << R"({"camera": "", "env": "", "part": ""})";
  const RunResult config = run_ssdo(base + " --config " + (out / "cfg.json"));
  EXPECT_EQ(config.exit_code, 0) << config.output;
  EXPECT_TRUE(fs::exists(out.path / "cornell.ssdo.exr"));
}

// --guard-band PX: every term is computed on the whole (overscan) frame, then cropped: the
// output is the inner picture, pixel for pixel the inner pixels of the uncropped run.
TEST(OptionsCli, GuardBandCropsEveryTermToTheInnerPicture) {
  ScratchDir out;
  const std::string flags = "--terms ao,composite --method gtao --preset low";
  const Image whole = process(out, "whole", flags);
  const Image inner = process(out, "inner", flags + " --guard-band 16");
  ASSERT_EQ(whole.width, 640);
  ASSERT_EQ(whole.height, 360);
  EXPECT_EQ(inner.width, 640 - 32);
  EXPECT_EQ(inner.height, 360 - 32);
  ASSERT_EQ(inner.channels, whole.channels);
  ASSERT_GE(whole.channel("ao"), 0);
  size_t differing = 0;
  for (int y = 0; y < inner.height; ++y)
    for (int x = 0; x < inner.width; ++x)
      for (size_t c = 0; c < inner.channels.size(); ++c)
        differing += inner.at(x, y, int(c)) != whole.at(x + 16, y + 16, int(c));
  EXPECT_EQ(differing, 0u);

  ScratchDir small;
  const RunResult r =
      run_ssdo("process " + example("cornell.exr") + " -o " + small.path.string() + " --guard-band 180");
  EXPECT_EQ(r.exit_code, 1) << r.output;  // the frame's error: nothing is left of 640x360
  EXPECT_NE(r.output.find("leaves nothing"), std::string::npos) << r.output;
}

// --multibounce: Jimenez et al.'s fit only brightens AO (the light bounced between surfaces
// of the frame's albedo), and does so somewhere on a frame with albedo.
TEST(OptionsCli, MultibounceBrightensAoWithTheFramesAlbedo) {
  ScratchDir out;
  const std::string flags = "--terms ao --method gtao --preset low";
  const Image single = process(out, "single", flags);
  const Image multi = process(out, "multi", flags + " --multibounce");
  const int c = single.channel("ao");
  ASSERT_GE(c, 0);
  ASSERT_EQ(multi.pixels.size(), single.pixels.size());
  size_t darker = 0, brighter = 0;
  for (int y = 0; y < single.height; ++y)
    for (int x = 0; x < single.width; ++x) {
      const float a = single.at(x, y, c), b = multi.at(x, y, c);
      darker += b < a - 1e-3f;
      brighter += b > a + 1e-3f;
    }
  EXPECT_EQ(darker, 0u);
  EXPECT_GT(brighter, size_t(single.width) * single.height / 100);
}

}  // namespace
}  // namespace ssdo::test
