#include <gtest/gtest.h>

#include "service/cli_options.h"
#include "service/pipeline.h"

namespace ssdo {
namespace {

TEST(Terms, ParsesListsAndAll) {
  TermSelection t;
  std::string error;
  ASSERT_TRUE(parse_terms("ao,ssdo", t, error));
  EXPECT_TRUE(t.ao);
  EXPECT_TRUE(t.ssdo);
  EXPECT_FALSE(t.composite);
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
