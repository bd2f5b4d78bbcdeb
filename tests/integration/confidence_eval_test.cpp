// `ssdo eval` reports the error per confidence decile; on real frames the low-confidence
// pixels err more than the high-confidence ones: on the orbit shot with its frames as each
// other's views (the confidence then counts what any view observed) and on the shared
// single frames (cornell, greeble, depthgap: the frame's own observation).
#include <nlohmann/json.hpp>

#include "service_harness.h"
#include "tests/support/skips.h"

namespace ssdo::test {
namespace {

struct Deciles {
  double low_mae = 0, high_mae = 0;  // pixel-weighted: confidence < 0.5, >= 0.9
  double high_share = 0;             // fraction of pixels at >= 0.9
};

// The run's overall deciles from `ssdo eval --json`.
Deciles eval_deciles(const std::string& args) {
  const RunResult r = run_ssdo("eval " + args + " --preset medium --json");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  const nlohmann::json& bins = j.at("overall").at("confidence_deciles");
  EXPECT_EQ(bins.size(), 10u);
  double low_sum = 0, low_n = 0, all_n = 0;
  for (size_t b = 0; b < 5; ++b) {
    low_sum += bins[b].at("mae").get<double>() * bins[b].at("pixels").get<double>();
    low_n += bins[b].at("pixels").get<double>();
  }
  for (const auto& bin : bins) all_n += bin.at("pixels").get<double>();
  EXPECT_EQ(all_n, j.at("overall").at("pixels").get<double>()) << "every compared pixel is in one bin";
  EXPECT_GT(low_n, 0.01 * all_n);
  return {low_sum / std::max(low_n, 1.0), bins[9].at("mae").get<double>(), bins[9].at("pixels").get<double>() / all_n};
}

TEST(ConfidenceEval, LowConfidenceErrsMoreOnTheOrbitAndTheSharedFrames) {
  SSDO_SKIP_IN_SANITIZER_BUILD("the confidence's error table over the shared frames and the orbit; its code runs in the unit tests");
  const fs::path dir = shared_dir() / "gbuffers";
  if (!fs::exists(dir / "orbit_f6.exr")) GTEST_SKIP() << "no shared frames at " << dir;
  std::string orbit;
  for (int i = 0; i <= 6; ++i) orbit.append(" ").append((dir / numbered("orbit_f", i)).string()).append(".exr");
  // Measured (2026-12-06, gtao medium, its thickness from silhouettes), MAE of the lower half
  // | the top decile: orbit with views 0.033 | 0.016, alone 0.029 | 0.014; shared frames
  // 0.048 | 0.019. (With the constant thickness the lower half erred 0.19, 0.12 and 0.085:
  // the silhouettes removed most of the error the confidence flags, thin occluders'.)
  const Deciles with_views = eval_deciles(orbit + " --views 2");
  const Deciles alone = eval_deciles(orbit + " --views 0");
  std::string shared_frames;
  for (const char* name : {"cornell.exr", "greeble.exr", "depthgap.exr"})
    shared_frames.append(" ").append((dir / name).string());
  const Deciles shared = eval_deciles(shared_frames);
  EXPECT_GT(with_views.low_mae, 1.8 * with_views.high_mae);
  EXPECT_GT(alone.low_mae, 1.8 * alone.high_mae);
  EXPECT_GT(shared.low_mae, 2.0 * shared.high_mae);
  // What the views observe moves pixels up to the top decile (28% -> 65%), whose error
  // stays that of the pixels the frame alone saw whole.
  EXPECT_GT(with_views.high_share, 2.0 * alone.high_share);
  EXPECT_LT(with_views.high_mae, 1.25 * alone.high_mae);
}

}  // namespace
}  // namespace ssdo::test
