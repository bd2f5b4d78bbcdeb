// The render-farm contract of `ssdo process` (examples/slurm/, docs/usage.md, "Render farms"):
// chunks never overlap and cover every frame, a task whose range overshoots the shot's end
// is clipped with --shot-frames, a missing frame inside the shot still fails, and a task
// run twice skips what it already wrote. The same contract under a real Slurm cluster:
// tests/slurm/slurm_array_test.sh.
#include <filesystem>
#include <map>
#include <numeric>
#include <regex>

#include <gtest/gtest.h>

#include "run_binary.h"
#include "service/frame_range.h"

namespace ssdo::test {
namespace {

namespace fs = std::filesystem;

std::vector<int> ranges(const std::string& spec) {
  std::vector<int> f;
  std::string error;
  EXPECT_TRUE(parse_frame_ranges(spec, f, error)) << spec << ": " << error;
  return f;
}

// shot.NNNN.exr + shot.NNNN.camera.json copies of an example frame in `dir`.
void make_frames(const fs::path& dir, const std::vector<int>& numbers) {
  const fs::path examples = source_dir() / "examples" / "frames";
  for (int f : numbers) {
    char name[32];
    std::snprintf(name, sizeof name, "shot.%04d", f);
    fs::copy_file(examples / "cornell.exr", dir / (std::string(name) + ".exr"));
    fs::copy_file(examples / "cornell.camera.json", dir / (std::string(name) + ".camera.json"));
  }
}

// Frame number -> how many "-> OUT/shot.NNNN.ssdo.exr: ok" lines the output holds.
std::map<int, int> computed(const std::string& output) {
  std::map<int, int> n;
  static const std::regex ok(R"(shot\.(\d{4})\.ssdo\.exr: ok)");
  for (auto it = std::sregex_iterator(output.begin(), output.end(), ok); it != std::sregex_iterator(); ++it)
    ++n[std::stoi((*it)[1])];
  return n;
}

TEST(FarmFrames, FormatReadsBackAsTheSameList) {
  for (const char* spec : {"1-24", "1-3,5-9x2,12", "24-1", "-5--1", "1,3", "4-5", "7", "1-10,10,10-1",
                           "1-100x2,200", "3,1,2", "0-30x10,31"}) {
    const std::vector<int> frames = ranges(spec);
    const std::string formatted = format_frame_ranges(frames);
    EXPECT_EQ(ranges(formatted), frames) << spec << " -> " << formatted;
  }
  EXPECT_EQ(format_frame_ranges({1, 2, 3, 5, 7, 9, 12}), "1-3,5-9x2,12");
  EXPECT_EQ(format_frame_ranges({}), "");
}

TEST(FarmFrames, ClipKeepsOnlyTheShotsFrames) {
  std::string clipped, error;
  size_t dropped = 0;
  ASSERT_TRUE(clip_frame_ranges("21-25", "1-24", clipped, error, &dropped)) << error;
  EXPECT_EQ(clipped, "21-24");
  EXPECT_EQ(dropped, 1u);
  ASSERT_TRUE(clip_frame_ranges("1-5", "1-24", clipped, error, &dropped));
  EXPECT_EQ(clipped, "1-5");
  EXPECT_EQ(dropped, 0u);
  ASSERT_TRUE(clip_frame_ranges("25-29", "1-24", clipped, error, &dropped));
  EXPECT_EQ(clipped, "");  // a task entirely past the end: nothing to do
  EXPECT_EQ(dropped, 5u);
  ASSERT_TRUE(clip_frame_ranges("0-6", "1-24x2", clipped, error));  // the shot's own step
  EXPECT_EQ(clipped, "1-5x2");
  EXPECT_FALSE(clip_frame_ranges("21-25", "1-", clipped, error));
  EXPECT_FALSE(error.empty());
}

TEST(FarmFrames, ChunksCoverEveryFrameOnce) {
  for (size_t frames : {1u, 5u, 23u, 24u, 25u, 240u}) {
    std::vector<int> all(frames);
    std::iota(all.begin(), all.end(), 1);
    for (int n : {1, 2, 3, 4, 7, 24, 30}) {
      std::vector<int> joined;
      size_t smallest = frames, largest = 0;
      for (int i = 1; i <= n; ++i) {
        const std::vector<int> slice = chunk_slice(all, i, n);
        joined.insert(joined.end(), slice.begin(), slice.end());
        smallest = std::min(smallest, slice.size());
        largest = std::max(largest, slice.size());
      }
      EXPECT_EQ(joined, all) << frames << " frames in " << n << " chunks";  // in order, once each
      EXPECT_LE(largest - smallest, 1u) << frames << " frames in " << n << " chunks";
    }
  }
}

// Every chunk of a pattern run by the binary: each frame computed by exactly one task.
TEST(FarmFrames, ChunkTasksWriteEachOutputOnce) {
  ScratchDir dir;
  make_frames(dir.path, {1, 2, 3, 4, 5, 6, 7});
  const std::string common = "process '" + dir / "shot.####.exr" + "' --frames 1-7 -o " + dir / "out" +
                             " --terms ao --preset low --temporal 0 --chunk ";  // frames alone in time
  std::map<int, int> total;
  for (int i = 1; i <= 3; ++i) {
    const RunResult r = run_ssdo(common + std::to_string(i) + "/3");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    for (const auto& [frame, count] : computed(r.output)) total[frame] += count;
  }
  ASSERT_EQ(total.size(), 7u);
  for (const auto& [frame, count] : total) EXPECT_EQ(count, 1) << "frame " << frame;
  // A task run again (requeued, or a rerun of a failed job): nothing recomputed, exit 0.
  const RunResult again = run_ssdo(common + "2/3");
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_TRUE(computed(again.output).empty()) << again.output;
  for (const auto& e : fs::directory_iterator(dir.path / "out"))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

// Deadline / OpenCue hand the last task --frames 21-25 when the shot ends at 24.
TEST(FarmFrames, OvershootingLastTaskIsClippedToTheShot) {
  ScratchDir dir;
  make_frames(dir.path, {21, 22, 23, 24});
  const std::string base =
      "process '" + dir / "shot.####.exr" + "' -o " + dir / "out" + " --terms ao --preset low --temporal 0 ";

  // Without the shot's range, frame 25 is a missing frame of the request: a failure.
  RunResult r = run_ssdo(base + "--frames 21-25");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("shot.0025.exr"), std::string::npos) << r.output;

  fs::remove_all(dir.path / "out");
  r = run_ssdo(base + "--frames 21-25 --shot-frames 1-24");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(computed(r.output).size(), 4u) << r.output;
  EXPECT_EQ(r.output.find("shot.0025.exr"), std::string::npos) << r.output;
  for (int f : {21, 22, 23, 24}) EXPECT_TRUE(fs::exists(dir.path / "out" / ("shot.00" + std::to_string(f) + ".ssdo.exr")));

  // A task wholly past the shot's end has nothing to do.
  r = run_ssdo(base + "--frames 26-30 --shot-frames 1-24");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(computed(r.output).empty()) << r.output;

  // A frame missing inside the shot still fails its task.
  fs::remove(dir.path / "shot.0023.exr");
  r = run_ssdo(base + "--frames 21-25 --shot-frames 1-24 --force");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("shot.0023.exr"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("shot.0025.exr"), std::string::npos) << r.output;

  // Usage errors: --shot-frames without --frames, a malformed shot range.
  EXPECT_EQ(run_ssdo(base + "--shot-frames 1-24 " + dir / "shot.0021.exr").exit_code, 2);
  EXPECT_EQ(run_ssdo(base + "--frames 21-25 --shot-frames 1-").exit_code, 2);
}

}  // namespace
}  // namespace ssdo::test
