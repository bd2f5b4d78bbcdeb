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

}  // namespace
}  // namespace ssdo::test
