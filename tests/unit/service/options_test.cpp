#include <gtest/gtest.h>

#include "service/cli_options.h"
#include "service/pipeline.h"

namespace ssdo {
namespace {

TEST(Terms, ParsesListsAndAll) {
  TermSelection t;
  std::string error;
  ASSERT_TRUE(parse_terms("ao", t, error));
  EXPECT_TRUE(t.ao);
  EXPECT_FALSE(t.ssdo);
  EXPECT_FALSE(t.composite);
  // SSDO comes with the composite it lights.
  ASSERT_TRUE(parse_terms("ao,ssdo", t, error));
  EXPECT_TRUE(t.ao);
  EXPECT_TRUE(t.ssdo);
  EXPECT_TRUE(t.composite);
  ASSERT_TRUE(parse_terms("all", t, error));
  EXPECT_TRUE(t.ao && t.ssdo && t.composite);
  EXPECT_EQ(to_string(t), "ao,ssdo,composite");
}

TEST(Terms, UnknownOrEmptyIsAnError) {
  TermSelection t;
  std::string error;
  EXPECT_FALSE(parse_terms("ao,fog", t, error));
  EXPECT_NE(error.find("fog"), std::string::npos);
  EXPECT_FALSE(parse_terms(",", t, error));
}

TEST(ReadOptionArgs, MapsChannelsSpacesAndReferences) {
  ReadOptionArgs a;
  a.maps = {"depth=Z", "normal=N", "normal-space=view", "ref:AO=occlusion.R"};
  a.fov_x_deg = 50;
  a.depth_kind = "radial";
  ReadOptions r;
  std::string error;
  ASSERT_TRUE(resolve_read_options(a, r, error)) << error;
  EXPECT_EQ(r.mapping.depth, "Z");
  EXPECT_EQ(r.mapping.normal, "N");
  EXPECT_EQ(r.mapping.normal_space, Space::view);
  EXPECT_EQ(r.mapping.references.at("AO"), "occlusion.R");
  ASSERT_TRUE(r.fov_x_deg.has_value());
  EXPECT_FLOAT_EQ(*r.fov_x_deg, 50.0f);
  EXPECT_EQ(r.depth_kind, DepthKind::radial);
}

TEST(ReadOptionArgs, BadMapsNameTheProblem) {
  ReadOptions r;
  std::string error;
  ReadOptionArgs a;
  a.maps = {"depthZ"};
  EXPECT_FALSE(resolve_read_options(a, r, error));
  EXPECT_NE(error.find("INPUT=CHANNEL"), std::string::npos);
  a.maps = {"colour=C"};
  EXPECT_FALSE(resolve_read_options(a, r, error));
  EXPECT_NE(error.find("colour"), std::string::npos);
  a.maps = {"normal-space=screen"};
  EXPECT_FALSE(resolve_read_options(a, r, error));
  EXPECT_NE(error.find("world or view"), std::string::npos);
}

TEST(ComputeOptionArgs, PresetThenOverrides) {
  ComputeOptionArgs a;
  a.method = "hbao";
  a.preset = "high";
  a.radius_world = 2.5f;
  a.terms = "ao";
  FrameRequest req;
  std::string error;
  ASSERT_TRUE(resolve_compute_options(a, req, error)) << error;
  const AoSettings preset = ao_preset(AoMethod::hbao, Preset::high);
  EXPECT_EQ(req.ao.method, AoMethod::hbao);
  EXPECT_EQ(req.ao.directions, preset.directions);
  EXPECT_EQ(req.ao.steps, preset.steps);
  EXPECT_FLOAT_EQ(req.ao.radius_world, 2.5f);
  EXPECT_TRUE(req.terms.ao);
  EXPECT_FALSE(req.terms.composite);
}

}  // namespace
}  // namespace ssdo

namespace ssdo {
namespace {

TEST(Sky, AcceptsGreyAndColourSpellings) {
  glm::vec3 top, bottom;
  std::string error;
  ASSERT_TRUE(parse_sky("0.25:0.5:1,1:0.35:0.08", top, bottom, error)) << error;
  EXPECT_EQ(top, glm::vec3(0.25f, 0.5f, 1.0f));
  EXPECT_EQ(bottom, glm::vec3(1.0f, 0.35f, 0.08f));
  ASSERT_TRUE(parse_sky("0.25 0.5 1, 1 0.35 0.08", top, bottom, error)) << error;
  EXPECT_EQ(bottom, glm::vec3(1.0f, 0.35f, 0.08f));
  ASSERT_TRUE(parse_sky("0.25,0.5,1,1,0.35,0.08", top, bottom, error)) << error;
  EXPECT_EQ(top, glm::vec3(0.25f, 0.5f, 1.0f));
  ASSERT_TRUE(parse_sky("1,0.2", top, bottom, error)) << error;
  EXPECT_EQ(top, glm::vec3(1.0f));
  EXPECT_EQ(bottom, glm::vec3(0.2f));
}

TEST(Sky, RejectsMalformedColours) {
  glm::vec3 top, bottom;
  std::string error;
  for (const char* bad : {"", "1", "1,2,3", "red,blue", "1,-1", "1:2,3"}) {
    EXPECT_FALSE(parse_sky(bad, top, bottom, error)) << bad;
    EXPECT_NE(error.find("--sky"), std::string::npos) << bad;
  }
}

TEST(Composite, ModesAndWeightedLists) {
  std::vector<WeightedTerm> terms;
  std::string error;
  ASSERT_TRUE(parse_composite("ssao+ssdo", terms, error)) << error;
  EXPECT_EQ(terms.size(), composite_mode_terms(CompositeMode::ssao_ssdo).size());
  ASSERT_TRUE(parse_composite("ambient_ao:0.5,ssdo_indirect:2", terms, error)) << error;
  ASSERT_EQ(terms.size(), 2u);
  EXPECT_EQ(terms[0].term, CompositeTerm::ambient_ao);
  EXPECT_FLOAT_EQ(terms[0].weight, 0.5f);
  EXPECT_EQ(terms[1].term, CompositeTerm::ssdo_indirect);
  EXPECT_FLOAT_EQ(terms[1].weight, 2.0f);
  EXPECT_FALSE(parse_composite("glow", terms, error));
  EXPECT_NE(error.find("glow"), std::string::npos);
  EXPECT_FALSE(parse_composite("ambient:x", terms, error));
  EXPECT_FALSE(parse_composite("ambient:99", terms, error));
}

TEST(ComputeOptionArgs, OneEnvironmentAtATime) {
  ComputeOptionArgs a;
  a.sky = "1,0.5";
  a.env_constant = 2.0f;
  FrameRequest req;
  std::string error;
  EXPECT_FALSE(resolve_compute_options(a, req, error));
  EXPECT_NE(error.find("one environment"), std::string::npos);
  a.env_constant = 0;
  ASSERT_TRUE(resolve_compute_options(a, req, error)) << error;
  ASSERT_TRUE(req.environment);
  EXPECT_EQ(req.environment->kind(), EnvironmentKind::sky);
}

}  // namespace
}  // namespace ssdo

#include "service/quality.h"

namespace ssdo {
namespace {

TEST(Quality, FastestUnderTheErrorElseMostAccurate) {
  std::vector<CalibrationEntry> table;
  std::string error;
  ASSERT_TRUE(parse_calibration("# comment\nmethod,preset,samples,ms,mae\n"
                                "hemisphere,high,32,10,0.19\ngtao,medium,8,20,0.05\n"
                                "gtao,high,96,80,0.04\nraymarch,low,2048,9000,0.03\n",
                                table, error))
      << error;
  ASSERT_EQ(table.size(), 4u);
  bool met = false;
  CalibrationEntry c = choose_quality(table, 0.06, met);
  EXPECT_TRUE(met);
  EXPECT_EQ(c.method, AoMethod::gtao);
  EXPECT_EQ(c.preset, Preset::medium);
  c = choose_quality(table, 0.2, met);
  EXPECT_EQ(c.method, AoMethod::hemisphere);
  c = choose_quality(table, 0.01, met);  // nothing qualifies; the oracle is never chosen
  EXPECT_FALSE(met);
  EXPECT_EQ(c.method, AoMethod::gtao);
  EXPECT_EQ(c.preset, Preset::high);
  EXPECT_FALSE(parse_calibration("gtao,superb,1,2,3\n", table, error));
  EXPECT_NE(error.find("line 1"), std::string::npos);
}

TEST(Quality, ShippedTableCoversTheFastMethods) {
  const auto& table = shipped_calibration();
  ASSERT_GE(table.size(), 12u);
  bool met = false;
  const CalibrationEntry c = choose_quality(table, 0.5, met);
  EXPECT_TRUE(met);
  EXPECT_GT(c.ms, 0);
}

}  // namespace
}  // namespace ssdo
