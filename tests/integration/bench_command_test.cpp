// `ssdo bench` through the real binary: a CSV row per frame and preset with the row over all
// frames, the calibration table, the chart, and the shot variants (--views, --temporal)
// computed over the sequence among the files.
#include <map>
#include <sstream>

#include "service_harness.h"
#include "tests/support/skips.h"

namespace ssdo::test {
namespace {

struct AllRow {
  double ms = 0, mae = 0;
};

// bench.csv's rows over all frames, by preset.
std::map<std::string, AllRow> all_rows(const fs::path& csv) {
  std::map<std::string, AllRow> rows;
  std::istringstream in(read_text(csv));
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string file, method, preset, samples, resolution, ms, mae;
    if (std::getline(s, file, ',') && std::getline(s, method, ',') && std::getline(s, preset, ',') &&
        std::getline(s, samples, ',') && std::getline(s, resolution, ',') && std::getline(s, ms, ',') &&
        std::getline(s, mae, ',') && file == "all")
      rows[preset] = {std::stod(ms), std::stod(mae)};
  }
  return rows;
}

TEST(BenchCommand, WritesEveryPresetAndItsShotVariantWhichIsNoWorse) {
  SSDO_SKIP_IN_SANITIZER_BUILD("every preset up to ultra; the sequence context it runs is the Temporal and Sequence tests'");
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  std::string files;
  for (int i = 0; i < 3; ++i) files += " " + (shared_dir() / "gbuffers" / ("orbit_f" + std::to_string(i) + ".exr")).string();
  const RunResult r = run_ssdo("bench" + files + " --methods gtao --no-sweep --runs 1 --views 1 --temporal 1 -o " +
                               dir / "out");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::map<std::string, AllRow> rows = all_rows(dir.path / "out/bench.csv");
  for (const char* preset : {"low", "medium", "high", "ultra"}) {
    const std::string shot = std::string(preset) + "+v1+t1";
    ASSERT_TRUE(rows.count(preset) && rows.count(shot)) << preset << "\n" << read_text(dir.path / "out/bench.csv");
    EXPECT_GT(rows.at(preset).ms, 0.0) << preset;
    EXPECT_GT(rows.at(preset).mae, 0.0) << preset;
    EXPECT_LT(rows.at(preset).mae, 0.1) << preset;  // gtao against Cycles on the orbit: 0.04-0.06
    // Views and the temporal filter: never worse on the orbit (docs/temporal.md).
    EXPECT_LE(rows.at(shot).mae, rows.at(preset).mae) << shot;
  }
  EXPECT_LT(rows.at("high").mae, rows.at("low").mae);
  // The calibration table of --quality auto: a row per preset.
  std::istringstream calibration(read_text(dir.path / "out/calibration.csv"));
  int lines = 0;
  for (std::string line; std::getline(calibration, line);) ++lines;
  EXPECT_EQ(lines, 1 + 4);
  EXPECT_GT(fs::file_size(dir.path / "out/bench.png"), 10000u);
}

}  // namespace
}  // namespace ssdo::test
