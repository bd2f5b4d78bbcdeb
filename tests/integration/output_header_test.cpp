// An output EXR describes itself: its header, as OpenImageIO reads it, holds the camera
// (worldToCamera, worldToNDC), the producing version and the options (docs/usage.md, "What
// an output says about itself"), from both EXR writers; and each colour or vector term is
// one layer of three channels (layer.channel), each numeric term one channel.
#include <filesystem>
#include <map>
#include <set>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_binary.h"

namespace ssdo::test {
namespace {

struct Header {
  std::vector<std::string> channels;
  std::map<std::string, std::string> strings;
  std::map<std::string, std::vector<float>> matrices;
};

Header read_header(const std::string& path) {
  Header h;
  auto in = OIIO::ImageInput::open(path);
  if (!in) return h;
  const OIIO::ImageSpec& spec = in->spec();
  h.channels = spec.channelnames;
  for (const OIIO::ParamValue& p : spec.extra_attribs) {
    if (p.type() == OIIO::TypeDesc::STRING) h.strings[p.name().string()] = p.get_string();
    if (p.type() == OIIO::TypeDesc::TypeMatrix44) {
      const float* m = static_cast<const float*>(p.data());
      h.matrices[p.name().string()] = std::vector<float>(m, m + 16);
    }
  }
  return h;
}

TEST(OutputHeader, CarriesCameraVersionOptionsAndLayers) {
  ScratchDir dir;
  const std::string frame = (source_dir() / "examples/frames/cornell.exr").string();
  // zip goes through the writer's own chunk encoder, piz through OpenEXR's.
  for (const std::string compression : {"zip", "piz"}) {
    SCOPED_TRACE(compression);
    const std::string out = dir / compression;
    const RunResult r = run_ssdo("process " + frame + " -o " + out + " --terms all --method gtao --preset low" +
                                 " --env-constant 0.5 --threads 2 --compression " + compression);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const Header h = read_header(out + "/cornell.ssdo.exr");
    ASSERT_FALSE(h.channels.empty());

    EXPECT_EQ(h.strings.count("ssdo/version"), 1u);
    EXPECT_EQ(h.strings.at("ssdo/version").rfind("ssdo ", 0), 0u) << h.strings.at("ssdo/version");
    const nlohmann::json options = nlohmann::json::parse(h.strings.at("ssdo/options"), nullptr, false);
    ASSERT_TRUE(options.is_object()) << h.strings.at("ssdo/options");
    EXPECT_EQ(options.value("method", ""), "gtao");
    EXPECT_EQ(options.value("preset", ""), "low");
    EXPECT_EQ(options.value("terms", ""), "all");
    EXPECT_EQ(options.value("env-constant", 0.0), 0.5);
    EXPECT_EQ(options.value("compression", ""), compression);
    EXPECT_FALSE(options.contains("threads"));  // the same bytes for any thread count

    // The camera of the frame's sidecar: a rigid world-to-camera transform, and a
    // projection whose last row is not (0, 0, 0, 1).
    ASSERT_EQ(h.matrices.count("worldToCamera"), 1u);
    ASSERT_EQ(h.matrices.count("worldToNDC"), 1u);
    EXPECT_FLOAT_EQ(h.matrices.at("worldToCamera")[15], 1.0f);
    EXPECT_NE(h.matrices.at("worldToNDC")[11], 0.0f);

    // layer.channel: every dotted channel's layer has exactly three channels.
    std::map<std::string, std::set<std::string>> layers;
    for (const std::string& c : h.channels) {
      const size_t dot = c.find('.');
      if (dot == std::string::npos) layers[""].insert(c);
      else layers[c.substr(0, dot)].insert(c.substr(dot + 1));
    }
    EXPECT_EQ(layers["bent_normal"], (std::set<std::string>{"X", "Y", "Z"}));
    for (const char* colour : {"ssdo_direct", "ssdo_indirect", "composite", "ssdo_direct_denoised"})
      EXPECT_EQ(layers[colour], (std::set<std::string>{"R", "G", "B"})) << colour;
    EXPECT_EQ(layers[""], (std::set<std::string>{"ao", "ao_denoised", "confidence"}));
  }
}

}  // namespace
}  // namespace ssdo::test
