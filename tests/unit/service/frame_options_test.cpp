// The frame-option table (service/frame_options.h) and what is derived from it: the JSON
// schema, the command line, and the request the kernels validate.
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "service/cli_options.h"
#include "service/frame_options.h"
#include "service/guard_band.h"
#include "service/request_options.h"

namespace ssdo {
namespace {

using json = nlohmann::json;

bool numeric(const FrameOption& o) { return o.kind == OptionKind::number || o.kind == OptionKind::integer; }

// The largest value to try at the top of a range: an unbounded range takes any finite number.
double top(const FrameOption& o) { return std::isinf(o.hi) ? 1e30 : o.hi; }

json value_of(const FrameOption& o, double v) {
  return o.kind == OptionKind::integer ? json(static_cast<int64_t>(v)) : json(v);
}

// Parses `--NAME VALUE` (VALUE empty: a flag alone) with the options add_frame_options
// declares. True when CLI11 accepted it.
bool cli_accepts(const std::string& name, const std::string& value) {
  CLI::App app;
  FrameOptionArgs args;
  add_frame_options(app, args);
  std::vector<std::string> argv = {"--" + name};
  if (!value.empty()) argv.push_back(value);
  std::reverse(argv.begin(), argv.end());  // CLI11 takes a reversed vector
  try {
    app.parse(argv);
  } catch (const CLI::ParseError&) {
    return false;
  }
  return true;
}

std::string text(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

TEST(FrameOptionTable, NamesAreUniqueFlagNames) {
  std::set<std::string> seen;
  for (const FrameOption& o : frame_options()) {
    EXPECT_TRUE(seen.insert(o.name).second) << o.name;
    EXPECT_EQ(std::string(o.name).find('_'), std::string::npos) << o.name;
    EXPECT_NE(std::string(o.help), "") << o.name;
    if (numeric(o)) {
      EXPECT_LE(o.lo, o.hi) << o.name;
    }
    if (o.kind == OptionKind::choice) {
      EXPECT_FALSE(o.choices.empty()) << o.name;
    }
  }
  EXPECT_EQ(frame_option_keys().size(), frame_options().size());
}

// The table's ranges are the user-facing check; the kernels' validate() (called by
// resolve_frame_options) must accept both ends of every range, and the table must refuse
// what lies just outside.
TEST(FrameOptionTable, NumericRangesAreAcceptedByTheKernelsAtBothEnds) {
  for (const FrameOption& o : frame_options()) {
    if (!numeric(o)) continue;
    for (double v : {o.lo, top(o), 0.5 * (o.lo + top(o))}) {
      if (o.kind == OptionKind::integer) v = std::floor(v);
      FrameOptionArgs a;
      std::string error;
      ASSERT_TRUE(apply_json(json{{o.name, value_of(o, v)}}, a, error)) << o.name << " " << v << ": " << error;
      FrameRequest request;
      EXPECT_TRUE(resolve_frame_options(a, request, error)) << o.name << " = " << v << ": " << error;
    }
    const double step = o.kind == OptionKind::integer ? 1.0 : std::max(1e-3, 1e-3 * std::abs(o.lo));
    const double below = o.lo - step;
    if (!(o.zero_unset && below == 0)) {
      FrameOptionArgs a;
      std::string error;
      EXPECT_FALSE(apply_json(json{{o.name, value_of(o, below)}}, a, error)) << o.name << " = " << below;
      EXPECT_NE(error.find(o.name), std::string::npos) << error;
      EXPECT_NE(error.find(describe_range(o)), std::string::npos) << error;
    }
    if (!std::isinf(o.hi)) {
      FrameOptionArgs a;
      std::string error;
      EXPECT_FALSE(apply_json(json{{o.name, value_of(o, o.hi + 1)}}, a, error)) << o.name;
    }
  }
}

TEST(FrameOptionTable, CompressionDwaaNeedsColourTermsOnly) {
  for (const char* terms : {"ao,composite", "ao", "ssdo", "all"}) {
    FrameOptionArgs a;
    a.compression = "dwaa";
    a.compute.terms = terms;
    FrameRequest request;
    std::string error;
    EXPECT_FALSE(resolve_frame_options(a, request, error, /*build_environment=*/false)) << terms;
    EXPECT_NE(error.find("dwaa"), std::string::npos) << error;
  }
}

TEST(FrameOptionTable, EveryChoiceResolves) {
  for (const FrameOption& o : frame_options()) {
    if (o.kind != OptionKind::choice) continue;
    for (const std::string& c : o.choices) {
      FrameOptionArgs a;
      std::string error;
      ASSERT_TRUE(apply_json(json{{o.name, c}}, a, error)) << o.name << " " << c << ": " << error;
      // dwaa stores colour terms only: it resolves with the composite alone (and with the
      // default terms, which hold AO, is refused: CompressionDwaaNeedsColourTermsOnly).
      if (std::string(o.name) == "compression" && c == "dwaa") a.compute.terms = "composite";
      FrameRequest request;
      EXPECT_TRUE(resolve_frame_options(a, request, error, /*build_environment=*/false))
          << o.name << " = '" << c << "': " << error;
    }
    FrameOptionArgs a;
    std::string error;
    EXPECT_FALSE(apply_json(json{{o.name, "no-such-value"}}, a, error)) << o.name;
  }
}

// The command line and JSON accept the same values: each end of each range, just outside
// it, and each choice.
TEST(FrameOptionTable, CommandLineAndJsonAgree) {
  for (const FrameOption& o : frame_options()) {
    std::vector<std::pair<std::string, json>> cases;
    if (numeric(o)) {
      const double step = o.kind == OptionKind::integer ? 1.0 : 0.01;
      for (double v : {o.lo, top(o), o.lo - step, o.hi + step, 0.0})
        if (std::isfinite(v)) cases.emplace_back(text(v), value_of(o, v));
    }
    if (o.kind == OptionKind::choice) {
      for (const std::string& c : o.choices)
        if (!c.empty()) cases.emplace_back(c, json(c));
      cases.emplace_back("no-such-value", json("no-such-value"));
    }
    for (const auto& [cli_value, json_value] : cases) {
      FrameOptionArgs a;
      std::string error;
      EXPECT_EQ(cli_accepts(o.name, cli_value), apply_json(json{{o.name, json_value}}, a, error))
          << "--" << o.name << " " << cli_value;
    }
  }
  EXPECT_TRUE(cli_accepts("multibounce", ""));
  EXPECT_FALSE(cli_accepts("threads", "1.5"));
}

TEST(FrameOptionTable, CommandLineSetsTheFieldJsonSets) {
  CLI::App app;
  FrameOptionArgs cli;
  add_frame_options(app, cli);
  std::vector<std::string> argv = {"--method", "hbao", "--radius", "0.5",       "--threads", "3",
                                   "--map",    "depth=Z", "--map", "normal=N", "--multibounce",
                                   "--guard-band", "8", "--png"};
  std::reverse(argv.begin(), argv.end());
  app.parse(argv);
  FrameOptionArgs from_json;
  std::string error;
  ASSERT_TRUE(apply_json(json{{"method", "hbao"},
                              {"radius", 0.5},
                              {"threads", 3},
                              {"map", {"depth=Z", "normal=N"}},
                              {"multibounce", true},
                              {"guard-band", 8},
                              {"png", true}},
                         from_json, error))
      << error;
  EXPECT_EQ(to_json(cli), to_json(from_json));
}

TEST(FrameOptionTable, MultibounceAndGuardBandReachTheRequest) {
  FrameOptionArgs a;
  std::string error;
  ASSERT_TRUE(apply_json(json{{"multibounce", true}, {"guard-band", 16}, {"terms", "ao"}}, a, error)) << error;
  FrameRequest request;
  ASSERT_TRUE(resolve_frame_options(a, request, error)) << error;
  EXPECT_TRUE(request.ao.multibounce);
  EXPECT_EQ(request.guard_band_px, 16);
  EXPECT_TRUE(reads_for(request).read_albedo);  // the multi-bounce fit needs the albedo
  FrameRequest plain;
  ASSERT_TRUE(resolve_frame_options(FrameOptionArgs{}, plain, error)) << error;
  EXPECT_FALSE(plain.ao.multibounce);
  EXPECT_EQ(plain.guard_band_px, 0);
}

TEST(FrameOptionTable, MarkdownHasARowPerOption) {
  const std::string md = frame_options_markdown();
  for (const FrameOption& o : frame_options())
    EXPECT_NE(md.find("| `--" + std::string(o.name) + "` |"), std::string::npos) << o.name;
}

// The cropped terms keep the rays of their pixels: a view-space point lands PX pixels
// up and left of where the whole frame's camera put it.
TEST(GuardBand, CropKeepsEachPixelsRay) {
  Camera camera = Camera::from_fov_x(64, 48, 60.0f);
  const Camera whole = camera;
  ComputedFrame frame;
  cv::Mat ao(48, 64, CV_32FC1);
  for (int y = 0; y < ao.rows; ++y)
    for (int x = 0; x < ao.cols; ++x) ao.at<float>(y, x) = float(y * 100 + x);
  frame.terms.push_back({"ao", ao, SampleType::half, false});
  ASSERT_EQ(crop_guard_band(frame, camera, 4), "");
  EXPECT_EQ(camera.width_px, 56);
  EXPECT_EQ(camera.height_px, 40);
  ASSERT_EQ(frame.terms[0].image.size(), cv::Size(56, 40));
  EXPECT_EQ(frame.terms[0].image.at<float>(0, 0), 404.0f);
  for (const glm::vec3 p : {glm::vec3(0.3f, -0.2f, -2.0f), glm::vec3(-1.0f, 0.5f, -5.0f)}) {
    const glm::vec2 a = whole.pixel_from_view(p), b = camera.pixel_from_view(p);
    EXPECT_NEAR(b.x, a.x - 4.0f, 1e-3f);
    EXPECT_NEAR(b.y, a.y - 4.0f, 1e-3f);
  }
  Camera tiny = Camera::from_fov_x(8, 8, 60.0f);
  EXPECT_NE(crop_guard_band(frame, tiny, 4), "");
  ComputedFrame untouched;
  Camera same = whole;
  EXPECT_EQ(crop_guard_band(untouched, same, 0), "");
  EXPECT_EQ(same.view_to_clip, whole.view_to_clip);
}

}  // namespace
}  // namespace ssdo
