// `ssdo eval` compares each term, raw or denoised, with its pass: SSDO's light terms of a
// lone frame are kept in half (nothing but the output reads the raw ones), and eval reads
// them as they are.
#include <nlohmann/json.hpp>

#include "service_harness.h"

namespace ssdo::test {
namespace {

// The overall MAE of `ssdo eval --json` on the frame with `args`.
double eval_mae(const fs::path& frame, const std::string& args) {
  const RunResult r =
      run_ssdo("eval " + frame.string() + " " + args + " --preset low --views 0 --temporal 0 --json");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  if (r.exit_code != 0) return -1.0;
  return nlohmann::json::parse(r.output.substr(r.output.find('{'))).at("overall").at("mae").get<double>();
}

TEST(EvalTerms, RawAndDenoisedLightTermsAgainstTheirPasses) {
  const fs::path frame = shared_dir() / "gbuffers" / "greeble.exr";
  if (!fs::exists(frame)) GTEST_SKIP() << "no shared frames at " << frame.parent_path();
  const std::string light = "--terms ssdo --env " + (frame.parent_path() / "env_equirect.exr").string() + " --term ";
  for (const std::string term : {"ssdo_direct --reference DiffDir", "ssdo_indirect --reference DiffInd"}) {
    const double raw = eval_mae(frame, light + term + " --raw");
    const double denoised = eval_mae(frame, light + term);
    // Measured (2026-11-28, SSDO low): direct 0.0667 raw, 0.0625 denoised; indirect 0.0295,
    // 0.0287. The denoise removes noise: the raw term errs more.
    EXPECT_GT(raw, 0.0) << term;
    EXPECT_LT(raw, 0.2) << term;
    EXPECT_GT(raw, denoised) << term;
  }
}

// Without an environment SSDO is lit by uniform radiance 1, not by the render's world:
// eval says so (the error then says nothing of the method), and not when one is given.
TEST(EvalTerms, ALightTermWithoutTheRendersEnvironmentIsNoted) {
  const fs::path frame = shared_dir() / "gbuffers" / "cornell.exr";
  if (!fs::exists(frame)) GTEST_SKIP() << "no shared frames at " << frame.parent_path();
  const std::string base =
      "eval " + frame.string() + " --term ssdo_direct --reference DiffDir --preset low --views 0 --temporal 0";
  const RunResult white = run_ssdo(base + " --json");
  ASSERT_EQ(white.exit_code, 0) << white.output;
  EXPECT_NE(white.output.find("note: no --env, --sky or --env-constant: ssdo_direct is lit by uniform radiance 1"),
            std::string::npos)
      << white.output;
  const RunResult lit = run_ssdo(base + " --env " + (frame.parent_path() / "env_equirect.exr").string());
  ASSERT_EQ(lit.exit_code, 0) << lit.output;
  EXPECT_EQ(lit.output.find("note: no --env"), std::string::npos) << lit.output;
  const RunResult ao = run_ssdo("eval " + frame.string() + " --reference AO --preset low --views 0 --temporal 0");
  ASSERT_EQ(ao.exit_code, 0) << ao.output;
  EXPECT_EQ(ao.output.find("note: no --env"), std::string::npos) << ao.output;
}

// The GTAO presets' thickness from silhouettes (kernels/thickness.h) through the product:
// the AO of the greeble frame and of cornell against Cycles, by default and with
// --thickness-model constant or a --thickness, and the option's conflict with --thickness.
TEST(EvalTerms, ThicknessFromSilhouettesAgainstCycles) {
  const fs::path dir = shared_dir() / "gbuffers";
  if (!fs::exists(dir / "greeble.exr")) GTEST_SKIP() << "no shared frames at " << dir;
  // Measured (2026-12-07, gtao low, its slices pooled): greeble 0.0501 -> 0.0238, cornell 0.0959 -> 0.0840.
  for (const std::string name : {"greeble.exr", "cornell.exr"}) {
    const double constant = eval_mae(dir / name, "--reference AO --thickness-model constant");
    const double silhouettes = eval_mae(dir / name, "--reference AO");
    EXPECT_GT(silhouettes, 0.0) << name;
    EXPECT_LT(silhouettes, 0.95 * constant) << name;
    EXPECT_EQ(eval_mae(dir / name, "--reference AO --thickness-model silhouettes"), silhouettes) << name;
    // A thickness given is a constant one: the automatic constant, 0.5 x the radius of 1.
    EXPECT_EQ(eval_mae(dir / name, "--reference AO --thickness 0.5"), constant) << name;
  }
  // Against the oracle, which takes the request's thickness model: GTAO with the silhouettes
  // errs no more against it than with the constant against its own; an oracle that kept the
  // constant would add the models' difference (measured on greeble, gtao low against
  // raymarch low: 0.0251 with the silhouettes, 0.0296 with the constant; gtao medium 0.0194
  // and 0.0237; with low's slices alone, not pooled, 0.0383 and 0.0382, and 0.0443 had the
  // oracle kept the constant).
  const fs::path greeble = dir / "greeble.exr";
  const double silhouettes_vs_oracle = eval_mae(greeble, "--against-oracle low");
  const double constant_vs_oracle = eval_mae(greeble, "--against-oracle low --thickness-model constant");
  EXPECT_GT(silhouettes_vs_oracle, 0.0);
  EXPECT_LT(silhouettes_vs_oracle, constant_vs_oracle + 0.003);
  const RunResult both = run_ssdo("eval " + (dir / "cornell.exr").string() +
                                  " --reference AO --thickness 0.3 --thickness-model silhouettes");
  EXPECT_EQ(both.exit_code, 2) << both.output;
  EXPECT_NE(both.output.find("give --thickness (a constant thickness) or --thickness-model silhouettes, not both"),
            std::string::npos)
      << both.output;
}

}  // namespace
}  // namespace ssdo::test
