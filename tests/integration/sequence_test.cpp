// A shot's frames as extra views of each other (--views): which neighbours each frame gets,
// each file read once per batch, a farm chunk's neighbours outside it, inconsistent
// neighbours skipped, resumption after kill -9, the watch mode's neighbours from its
// folder; and the radius every command takes from the frame's sidecar.
#include <fstream>
#include <regex>
#include <set>

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>

#include "service_harness.h"
#include "tests/support/skips.h"

namespace ssdo::test {
namespace {

fs::path orbit(int n, const char* ext) { return shared_dir() / "gbuffers" / ("orbit_f" + std::to_string(n) + ext); }

// Orbit frame `n` as DIR/NAME.exr + its sidecar (sidecar first: the frame is the file a
// watching service reacts to).
void copy_orbit_frame(const fs::path& dir, const std::string& name, int n) {
  fs::copy_file(orbit(n, ".camera.json"), dir / (name + ".camera.json"));
  fs::copy_file(orbit(n, ".exr"), dir / (name + ".exr"));
}

// The orbit frames 0..count-1 (5 degrees per frame) as DIR/STEM<N>.exr + sidecars.
void copy_orbit(const fs::path& dir, const std::string& stem, int count, int first_number = 0) {
  fs::create_directories(dir);
  for (int i = 0; i < count; ++i) copy_orbit_frame(dir, numbered(stem.c_str(), first_number + i), i);
}

// The "views: ..." note of the frame line of `input` (the lines after it up to the next frame).
std::string views_note(const std::string& log, const std::string& input) {
  const size_t at = log.find(input + " -> ");
  if (at == std::string::npos) return "";
  const size_t note = log.find("note: views:", at);
  const size_t next = log.find("\n[", at);
  if (note == std::string::npos || (next != std::string::npos && note > next)) return "";
  return log.substr(note, log.find('\n', note) - note);
}

// The frame numbers of the views a note names ("views: f1 f3 (...)" -> {1, 3}).
std::vector<int> view_numbers(const std::string& note, const std::string& stem) {
  std::vector<int> n;
  const std::string names = note.substr(0, note.find(" ("));
  const std::regex re(stem + "(\\d+)\\.exr");
  for (std::sregex_iterator it(names.begin(), names.end(), re), end; it != end; ++it) n.push_back(std::stoi((*it)[1]));
  return n;
}

// From the last "views:" note of a batch: files read in all and read whole.
struct Reads {
  int files = -1, whole = -1;
};
Reads last_reads(const std::string& log) {
  const std::regex re("\\(read (\\d+) files? for \\d+ frames?: (\\d+) whole");
  Reads r;
  for (std::sregex_iterator it(log.begin(), log.end(), re), end; it != end; ++it)
    r = {std::stoi((*it)[1]), std::stoi((*it)[2])};
  return r;
}

TEST(Sequence, EachFrameGetsViewsOnBothSidesAndEveryFileIsReadOnce) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 7);
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" +
                               " --views 1 --temporal 0 --terms ao --preset low --jobs 1 -v");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (int i = 0; i < 7; ++i) {
    const std::string note = views_note(r.output, dir / ("in/" + numbered("orbit_f", i) + ".exr"));
    ASSERT_FALSE(note.empty()) << i << "\n" << r.output;
    const std::vector<int> views = view_numbers(note, "orbit_f");
    // One view on each side where the frame has neighbours on that side, never itself.
    const int before = int(std::count_if(views.begin(), views.end(), [&](int v) { return v < i; }));
    const int after = int(std::count_if(views.begin(), views.end(), [&](int v) { return v > i; }));
    EXPECT_EQ(before, i > 0 ? 1 : 0) << note;
    EXPECT_EQ(after, i < 6 ? 1 : 0) << note;
  }
  // One worker computing the whole shot: every file read once, whole (the views ahead are
  // read whole and kept for their own frame).
  const Reads reads = last_reads(r.output);
  EXPECT_EQ(reads.files, 7) << r.output;
  EXPECT_EQ(reads.whole, 7) << r.output;
}

TEST(Sequence, ViewsZeroIsTheFrameAlone) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 3);
  // Each file given alone is no sequence: it gets no views whatever --views says.
  for (int i = 0; i < 3; ++i) {
    const std::string name = numbered("orbit_f", i);
    const RunResult alone = run_ssdo("process " + dir / ("in/" + name + ".exr") + " -o " + dir / "out0" +
                                     " --views 0 --temporal 0 --terms ao --preset low -v");
    ASSERT_EQ(alone.exit_code, 0) << alone.output;
    EXPECT_EQ(alone.output.find("views:"), std::string::npos) << alone.output;
  }
  // The folder is a sequence: with no views and no temporal neighbours, each frame is the
  // frame alone.
  const RunResult zero =
      run_ssdo("process " + dir / "in" + " -o " + dir / "outz" + " --views 0 --temporal 0 --terms ao --preset low");
  ASSERT_EQ(zero.exit_code, 0) << zero.output;
  for (int i = 0; i < 3; ++i) {
    const std::string name = numbered("orbit_f", i) + ".ssdo.exr";
    const std::string alone = exr_content(dir / ("out0/" + name));
    ASSERT_FALSE(alone.empty()) << name;
    EXPECT_TRUE(alone == exr_content(dir / ("outz/" + name))) << name;
  }
}

TEST(Sequence, AChunkReadsTheFramesJustOutsideItAsViewsOnly) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "shot.000", 7);  // shot.0000.exr .. shot.0006.exr
  // Chunk 2 of 3 of frames 0-6: frames 2 and 3.
  const RunResult r = run_ssdo("process '" + dir / "in/shot.####.exr" + "' --frames 0-6 --chunk 2/3 -o " +
                               dir / "out" + " --views 1 --temporal 0 --terms ao --preset low --jobs 1 -v");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> written;
  for (const auto& e : fs::directory_iterator(dir.path / "out")) written.push_back(e.path().filename().string());
  std::sort(written.begin(), written.end());
  EXPECT_EQ(written, (std::vector<std::string>{"shot.0002.ssdo.exr", "shot.0003.ssdo.exr"}));
  const std::vector<int> views2 = view_numbers(views_note(r.output, dir / "in/shot.0002.exr"), "shot\\.");
  ASSERT_EQ(views2.size(), 2u) << r.output;
  EXPECT_LT(views2[0], 2) << r.output;  // outside the chunk, read for its depth only
  // Frames 2 and 3 read whole once each; the views outside the chunk depth-only, once each.
  std::set<int> files = {2, 3};
  for (const char* frame : {"in/shot.0002.exr", "in/shot.0003.exr"})
    for (int v : view_numbers(views_note(r.output, dir / frame), "shot\\."))
      files.insert(v);
  const Reads reads = last_reads(r.output);
  EXPECT_EQ(reads.files, int(files.size())) << r.output;
  EXPECT_EQ(reads.whole, 2) << r.output;
}

TEST(Sequence, ANeighbourWithoutACameraIsSkippedWithANote) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 3);
  fs::remove(dir.path / "in/orbit_f1.camera.json");  // f1: only --fov, no world
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" +
                               " --views 2 --fov 40 --terms ao --preset low --jobs 1 -v");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("orbit_f1.exr: skipped as a view (no camera with a world transform)"), std::string::npos)
      << r.output;
  EXPECT_EQ(view_numbers(views_note(r.output, dir / "in/orbit_f0.exr"), "orbit_f"), (std::vector<int>{2}))
      << r.output;
}

// A neighbour whose header reads but whose pixels do not (a truncated file) is skipped as
// a view and the next frame on its side takes its place.
TEST(Sequence, AViewWhosePixelsDoNotReadIsReplacedByTheNextOne) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 4);
  const RunResult whole = run_ssdo("process " + dir / "in" + " -o " + dir / "out0" +
                                   " --views 1 --temporal 0 --terms ao --preset low --jobs 1 -v");
  ASSERT_EQ(whole.exit_code, 0) << whole.output;
  const std::vector<int> chosen = view_numbers(views_note(whole.output, dir / "in/orbit_f0.exr"), "orbit_f");
  ASSERT_EQ(chosen.size(), 1u) << whole.output;
  const std::string broken = numbered("orbit_f", chosen[0]) + ".exr";
  fs::resize_file(dir.path / "in" / broken, fs::file_size(dir.path / "in" / broken) / 2);
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" +
                               " --views 1 --temporal 0 --terms ao --preset low --jobs 1 -v");
  EXPECT_EQ(r.exit_code, 1) << r.output;  // the broken frame itself fails
  EXPECT_TRUE(path_exists(dir.path / "out/orbit_f0.ssdo.exr")) << r.output;
  EXPECT_NE(r.output.find(broken + ": skipped as a view (" + (dir / "in/") + broken + ": cannot read pixels"),
            std::string::npos)
      << r.output;
  const std::vector<int> now = view_numbers(views_note(r.output, dir / "in/orbit_f0.exr"), "orbit_f");
  ASSERT_EQ(now.size(), 1u) << r.output;
  EXPECT_NE(now[0], chosen[0]) << r.output;
}

// A neighbour that cannot be read, in a shot computed with views and temporal neighbours by
// one worker: its file is read once in the batch (not again for each frame that would use
// it, nor for its own turn), so the reads count each of the shot's files once; its own
// turn fails with the reason, and a frame that chose it as a view says so once.
TEST(Sequence, AnUnreadableNeighbourIsReadAndCountedOnce) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 7);
  const fs::path broken = dir.path / "in/orbit_f3.exr";
  fs::resize_file(broken, fs::file_size(broken) / 2);
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" +
                               " --views 2 --temporal 2 --terms ao --preset low --jobs 1 -v");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  const std::string reason = broken.string() + ": cannot read pixels";
  EXPECT_EQ(count_occurrences(r.output, "[4/7] " + dir / "in/orbit_f3.exr: FAILED: " + reason), 1) << r.output;
  const Reads reads = last_reads(r.output);
  EXPECT_EQ(reads.files, 7) << r.output;
  EXPECT_EQ(reads.whole, 7) << r.output;
  int skipped_as_view = 0;
  for (int i : {0, 1, 2, 4, 5, 6}) {
    const std::string frame = dir / ("in/" + numbered("orbit_f", i) + ".exr");
    const size_t at = r.output.find(frame + " -> ");
    ASSERT_NE(at, std::string::npos) << frame << "\n" << r.output;
    const std::string block = r.output.substr(at, r.output.find("\n[", at) - at);
    const int notes = count_occurrences(block, "orbit_f3.exr: skipped as a view (" + reason);
    EXPECT_LE(notes, 1) << block;
    skipped_as_view += notes;
    EXPECT_EQ(view_numbers(views_note(r.output, frame), "orbit_f").size() > 0, true) << block;
  }
  EXPECT_GE(skipped_as_view, 1) << r.output;
}

TEST(Sequence, KillNineMidBatchWithViewsThenRerunComputesEachFrameOnce) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  constexpr int kFrames = 7;
  copy_orbit(dir.path / "in", "orbit_f", kFrames);
  const fs::path out = dir.path / "out";
  auto outputs = [&] {
    int n = 0;
    for (int i = 0; i < kFrames; ++i) n += path_exists(out / (numbered("orbit_f", i) + ".ssdo.exr"));
    return n;
  };
  int finished_before = 0;
  // The kill lands mid-batch at kShotFrame's pace (service_harness.h).
  const std::string method = kShotFrame.method, preset = kShotFrame.preset;
  {
    SsdoProcess batch({"process", dir / "in", "-o", out.string(), "--jobs", "1", "--views", "2", "--terms", "ao",
                       "--method", method, "--preset", preset},
                      dir.path / "batch1.log");
    ASSERT_TRUE(wait_until([&] { return outputs() >= 1; }, 300)) << batch.log();
    ASSERT_EQ(batch.signal_and_wait(SIGKILL, 10), 128 + SIGKILL);
    EXPECT_TRUE(wait_until([&] { return workers_of(batch.pid()).empty(); }, 10));
    finished_before = outputs();
  }
  ASSERT_LT(finished_before, kFrames) << "the batch finished before it was killed";
  const RunResult r =
      run_ssdo("process " + dir / "in" + " -o " + out.string() + " --jobs 2 --views 2 --terms ao --method " + method +
               " --preset " + preset);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  char summary[64];
  std::snprintf(summary, sizeof summary, "done %d, skipped %d, failed 0", kFrames - finished_before, finished_before);
  EXPECT_NE(r.output.find(summary), std::string::npos) << r.output;
  EXPECT_EQ(outputs(), kFrames);
  EXPECT_TRUE(temp_files(out).empty());
}

// A re-rendered frame of a shot makes a rerun compute it and every frame that may take it
// as a view (those within kCandidateFramesPerView = 3 places for --views 1); the frames out
// of its reach stay up to date.
TEST(Sequence, ARerunComputesTheFramesWhoseNeighbourChanged) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 7);
  const std::string command = "process " + dir / "in" + " -o " + dir / "out" + " --views 1 --temporal 0 --terms ao --preset low";
  const RunResult first = run_ssdo(command);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("done 7, skipped 0, failed 0"), std::string::npos) << first.output;
  fs::last_write_time(dir.path / "in" / (numbered("orbit_f", 6) + ".exr"),
                      fs::file_time_type::clock::now() + std::chrono::seconds(5));
  const RunResult rerun = run_ssdo(command);
  ASSERT_EQ(rerun.exit_code, 0) << rerun.output;
  EXPECT_NE(rerun.output.find("done 4, skipped 3, failed 0"), std::string::npos) << rerun.output;
  for (int i = 0; i < 7; ++i)
    EXPECT_EQ(rerun.output.find(numbered("orbit_f", i) + ".exr: skipped") != std::string::npos, i < 3)
        << i << "\n" << rerun.output;
}

// The output says which neighbours its window held (ssdo/window): a rerun after a neighbour
// was deleted computes again the frames whose window held it (the mtimes alone cannot
// tell), and a chunk computed without its shot (--shot-frames) is computed again with it.
TEST(Sequence, ARerunComputesTheFramesWhoseWindowLostOrGainedAFrame) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 5);
  const std::string flags = " --views 1 --temporal 0 --terms ao --preset low";  // 3 places a side
  const std::string command = "process " + dir / "in" + " -o " + dir / "out" + flags;
  ASSERT_NE(run_ssdo(command).output.find("done 5, skipped 0, failed 0"), std::string::npos);
  fs::remove(dir.path / "in" / (numbered("orbit_f", 4) + ".exr"));
  fs::remove(dir.path / "in" / (numbered("orbit_f", 4) + ".camera.json"));
  const RunResult rerun = run_ssdo(command);
  EXPECT_NE(rerun.output.find("done 3, skipped 1, failed 0"), std::string::npos) << rerun.output;
  EXPECT_NE(rerun.output.find(numbered("orbit_f", 0) + ".exr: skipped"), std::string::npos) << rerun.output;
  EXPECT_NE(run_ssdo(command).output.find("done 0, skipped 4"), std::string::npos);
  // Frames 2-3 of a pattern alone, then as a chunk of the shot 0-3: computed again.
  const std::string pattern = " " + dir / "in/orbit_f@.exr" + " -o " + dir / "chunk" + flags + " --frames 2-3";
  ASSERT_NE(run_ssdo("process" + pattern).output.find("done 2, skipped 0"), std::string::npos);
  const RunResult chunk = run_ssdo("process" + pattern + " --shot-frames 0-3");
  EXPECT_NE(chunk.output.find("done 2, skipped 0"), std::string::npos) << chunk.output;
  EXPECT_NE(run_ssdo("process" + pattern + " --shot-frames 0-3").output.find("done 0, skipped 2"), std::string::npos);
}

// A socket request names its neighbours: they change the frame's AO, and each is confined
// like the input (one outside --allow is refused).
TEST(Sequence, SocketRequestViewsChangeTheFrameAndAreConfinedLikeItsInput) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  copy_orbit(dir.path / "in", "orbit_f", 3);
  copy_orbit(dir.path / "outside", "orbit_f", 3);
  const std::string socket = socket_path_for("views");
  SsdoProcess service({"serve", "--socket", socket, "-o", dir / "out", "--allow", dir / "in", "--terms", "ao",
                       "--preset", "low", "--frame-timeout", "60"},
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  Client c(socket);
  const std::string input = dir / "in/orbit_f1.exr", output = dir / "out/orbit_f1.ssdo.exr";
  const json alone = c.request({{"op", "process"}, {"input", input}});
  ASSERT_TRUE(alone.value("ok", false)) << alone.dump() << service.log();
  const std::vector<float> ao_alone = exr_channel_pixels(output, "ao");
  const json with = c.request(
      {{"op", "process"}, {"input", input}, {"views", {dir / "in/orbit_f0.exr", dir / "in/orbit_f2.exr"}}});
  ASSERT_TRUE(with.value("ok", false)) << with.dump() << service.log();
  const std::vector<float> ao_with = exr_channel_pixels(output, "ao");
  ASSERT_EQ(ao_alone.size(), ao_with.size());
  EXPECT_NE(ao_alone, ao_with);
  const json outside = c.request({{"op", "process"}, {"input", input}, {"views", {dir / "outside/orbit_f0.exr"}}});
  EXPECT_EQ(outside.value("code", ""), "forbidden") << outside.dump();
  // The same frame sent inline with views under --allow: they are used (an inline frame's
  // views were confined to its spool folder, and skipped). Its place in their shot is not
  // known (offsets 1, 2), so the views chosen among them may differ from the path's.
  std::string reply_bytes;
  const json inline_with = c.request({{"op", "process"},
                                      {"name", "orbit_f1"},
                                      {"sidecar", json::parse(read_text(dir.path / "in" / "orbit_f1.camera.json"))},
                                      {"views", {dir / "in/orbit_f0.exr", dir / "in/orbit_f2.exr"}},
                                      {"output", dir / "out/inline_f1.exr"}},
                                     read_text(input));
  ASSERT_TRUE(inline_with.value("ok", false)) << inline_with.dump() << service.log();
  EXPECT_EQ(inline_with.dump().find("skipped as a view"), std::string::npos) << inline_with.dump();
  EXPECT_NE(exr_channel_pixels(dir / "out/inline_f1.exr", "ao"), ao_alone);
}

// What the watch tests compute, for `serve` and for `process` alike: AO only, cheap.
const std::vector<std::string> kWatchCompute = {"--terms", "ao", "--preset", "low", "--threads", "2"};

// kWatchCompute as command-line words for run_ssdo, each after a space.
std::string process_compute() {
  std::string flags;
  for (const std::string& word : kWatchCompute) flags += " " + word;
  return flags;
}

// `ssdo serve --watch DIR/in -o DIR/served` with one worker.
std::vector<std::string> watch_args(const ScratchDir& dir, const std::string& socket,
                                    const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args = {"serve", "--watch", dir / "in", "-o", dir / "served", "--socket", socket,
                                   "--jobs", "1", "--frame-timeout", "60"};
  args.insert(args.end(), kWatchCompute.begin(), kWatchCompute.end());
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

// Waits until OUT holds STEM0..STEM<count-1>.ssdo.exr and the service has nothing queued
// or in flight.
bool wait_for_outputs(const std::string& socket, const fs::path& out, const std::string& stem, int count) {
  return wait_until(
      [&] {
        for (int i = 0; i < count; ++i)
          if (!path_exists(out / (numbered(stem.c_str(), i) + ".ssdo.exr"))) return false;
        const json s = stats(socket);
        return s.value("queue_depth", 1) == 0 && s.value("in_flight", 1) == 0;
      },
      60);
}

// The shot orbit_f0..f<frames-1> put in DIR/in, then served by the watch mode (watch_args
// with `extra`) until every frame has its output.
testing::AssertionResult serve_shot_already_there(const ScratchDir& dir, int frames, const std::string& name,
                                                  const std::vector<std::string>& extra = {}) {
  copy_orbit(dir.path / "in", "orbit_f", frames);
  const std::string socket = socket_path_for(name);
  SsdoProcess service(watch_args(dir, socket, extra), dir.path / "serve.log");
  if (!service.wait_for_log("ready", 30)) return testing::AssertionFailure() << "not ready: " << service.log();
  if (!wait_for_outputs(socket, dir.path / "served", "orbit_f", frames))
    return testing::AssertionFailure() << "outputs missing: " << service.log();
  return testing::AssertionSuccess();
}

// `ssdo process DIR/in -o DIR/<out> <extra>` with the watch tests' compute options.
void process_folder(const ScratchDir& dir, const std::string& out, const std::string& extra = "") {
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / out + extra + process_compute());
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

// The watch mode gives a frame the frames of its sequence already in the folder as views:
// with the whole shot there before the service starts, each output holds what `ssdo
// process` writes for the folder (the same header and samples, exr_content), and its AO is not the frame's alone.
TEST(SequenceWatch, FramesAlreadyInTheFolderAreViewsAsInProcess) {
  SSDO_SKIP_IN_SANITIZER_BUILD("a shot computed twice to compare the watch folder with a batch; each runs in its own tests");
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  constexpr int kFrames = 4;
  ASSERT_TRUE(serve_shot_already_there(dir, kFrames, "watchviews"));
  ASSERT_NO_FATAL_FAILURE(process_folder(dir, "batch"));
  ASSERT_NO_FATAL_FAILURE(process_folder(dir, "alone", " --views 0"));
  for (int i = 0; i < kFrames; ++i) {
    const std::string name = numbered("orbit_f", i) + ".ssdo.exr";
    const std::vector<float> served = exr_channel_pixels(dir / ("served/" + name), "ao");
    ASSERT_FALSE(served.empty()) << name;
    EXPECT_TRUE(exr_content(dir / ("served/" + name)) == exr_content(dir / ("batch/" + name))) << name;
    EXPECT_NE(served, exr_channel_pixels(dir / ("alone/" + name), "ao")) << name;
  }
}

// --views 0 in the watch mode: every frame of a sequence alone, the header and samples
// `ssdo process --views 0` writes.
TEST(SequenceWatch, ViewsZeroIsEachFrameAloneAsInProcess) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  constexpr int kFrames = 3;
  ASSERT_TRUE(serve_shot_already_there(dir, kFrames, "watchviews0", {"--views", "0"}));
  ASSERT_NO_FATAL_FAILURE(process_folder(dir, "alone", " --views 0"));
  for (int i = 0; i < kFrames; ++i) {
    const std::string name = numbered("orbit_f", i) + ".ssdo.exr";
    ASSERT_TRUE(exr_has_channel(dir / ("served/" + name), "ao")) << name;
    EXPECT_TRUE(exr_content(dir / ("served/" + name)) == exr_content(dir / ("alone/" + name))) << name;
  }
}

// Exactly once while the service runs: a frame computed before the rest of its sequence
// arrives keeps the output it got alone; the frames arriving later do not make it computed
// again. A restarted service computes it again (its window changed), as a batch over the
// folder would: after the restart both agree that every output is up to date.
TEST(SequenceWatch, AFrameComputedBeforeItsNeighboursArriveIsComputedAgainOnlyByARestart) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("lateviews");
  auto service = std::make_unique<SsdoProcess>(watch_args(dir, socket), dir.path / "serve.log");
  ASSERT_TRUE(service->wait_for_log("ready", 30)) << service->log();
  copy_orbit_frame(dir.path / "in", "orbit_f0", 0);
  ASSERT_TRUE(wait_for_outputs(socket, dir.path / "served", "orbit_f", 1)) << service->log();
  const fs::path first = dir.path / "served/orbit_f0.ssdo.exr";
  struct stat before {};
  ASSERT_EQ(::stat(first.c_str(), &before), 0);
  for (int i = 1; i < 4; ++i) copy_orbit_frame(dir.path / "in", numbered("orbit_f", i), i);
  ASSERT_TRUE(wait_for_outputs(socket, dir.path / "served", "orbit_f", 4)) << service->log();
  struct stat after {};
  ASSERT_EQ(::stat(first.c_str(), &after), 0);
  EXPECT_EQ(after.st_ino, before.st_ino) << "orbit_f0's output was written again";
  EXPECT_EQ(count_occurrences(service->log(), "ok " + dir / "in/orbit_f0.exr" + " ->"), 1) << service->log();
  // Written with the default --views, but nothing else of its sequence was there: its AO
  // is the frame's alone.
  const RunResult alone =
      run_ssdo("process " + dir / "in/orbit_f0.exr" + " -o " + dir / "alone" + " --views 0" + process_compute());
  ASSERT_EQ(alone.exit_code, 0) << alone.output;
  const std::vector<float> served = exr_channel_pixels(first.string(), "ao");
  ASSERT_FALSE(served.empty());
  EXPECT_EQ(served, exr_channel_pixels(dir / "alone/orbit_f0.ssdo.exr", "ao"));
  service.reset();
  SsdoProcess restarted(watch_args(dir, socket), dir.path / "serve2.log");
  ASSERT_TRUE(restarted.wait_for_log("ready", 30)) << restarted.log();
  EXPECT_TRUE(restarted.wait_for_log("ok " + dir / "in/orbit_f0.exr" + " ->", 60)) << restarted.log();
  ASSERT_TRUE(wait_for_outputs(socket, dir.path / "served", "orbit_f", 4)) << restarted.log();
  const RunResult batch = run_ssdo("process " + dir / "in" + " -o " + dir / "served" + process_compute());
  EXPECT_NE(batch.output.find("done 0, skipped 4"), std::string::npos) << batch.output << restarted.log();
}

// A frame whose sidecar says its AO pass used ao_distance `distance`, as DIR/STEM.exr.
void frame_with_ao_distance(const fs::path& dir, const std::string& stem, double distance) {
  fs::create_directories(dir);
  nlohmann::json sidecar = nlohmann::json::parse(read_text(example_frame("cornell.camera.json")));
  sidecar["ao_distance"] = distance;
  std::ofstream(dir / (stem + ".camera.json")) << sidecar.dump(2);
  fs::copy_file(example_frame("cornell.exr"), dir / (stem + ".exr"));
}

TEST(Radius, TheSidecarsAoDistanceIsTheDefaultAndTheFlagWins) {
  ScratchDir dir;
  frame_with_ao_distance(dir.path / "two", "f", 2.0);
  frame_with_ao_distance(dir.path / "one", "f", 1.0);
  auto run = [&](const std::string& in, const std::string& out, const std::string& flags) {
    const RunResult r = run_ssdo("process " + dir / in + " -o " + dir / out + " --terms ao --preset low " + flags);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return exr_channel_pixels(dir / (out + "/f.ssdo.exr"), "ao");
  };
  const std::vector<float> sidecar_two = run("two", "a", "");
  const std::vector<float> flag_two = run("one", "b", "--radius 2");
  const std::vector<float> sidecar_one = run("one", "c", "");
  const std::vector<float> flag_one_over_two = run("two", "d", "--radius 1");
  ASSERT_FALSE(sidecar_two.empty());
  EXPECT_EQ(sidecar_two, flag_two);
  EXPECT_NE(sidecar_two, sidecar_one);
  EXPECT_EQ(flag_one_over_two, sidecar_one);

  // serve (the watch folder) resolves it the same way.
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("radius");
  SsdoProcess service({"serve", "--watch", dir / "in", "-o", dir / "served", "--socket", socket, "--terms", "ao",
                       "--preset", "low"},
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  frame_with_ao_distance(dir.path / "in", "f", 2.0);
  ASSERT_TRUE(wait_until([&] { return path_exists(dir.path / "served/f.ssdo.exr"); }, 60)) << service.log();
  ASSERT_TRUE(service.wait_for_log("ok ", 10)) << service.log();
  EXPECT_EQ(exr_channel_pixels(dir / "served/f.ssdo.exr", "ao"), flag_two);

  // eval reports the radius it used.
  const RunResult eval = run_ssdo("eval " + dir / "two/f.exr" + " --reference AO --preset low --json");
  EXPECT_NE(eval.output.find("\"radius\": 2.0"), std::string::npos) << eval.output;
}

}  // namespace
}  // namespace ssdo::test
