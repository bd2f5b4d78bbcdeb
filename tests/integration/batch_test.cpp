// `ssdo process` as a production batch: worker isolation, resumption after kill -9,
// config files, the frame selection of a farm chunk.
#include <cstdlib>
#include <fstream>
#include <regex>

#include <OpenImageIO/imageio.h>

#include "service/build_features.h"
#include "service_harness.h"

namespace ssdo::test {
namespace {

std::string quoted_list(const std::vector<fs::path>& files) {
  std::string s;
  for (const auto& f : files) s += " '" + f.string() + "'";
  return s;
}

TEST(Batch, PoisonFramesFailOneByOneBatchFinishesWithExitOne) {
  SSDO_REQUIRE_CONFORMANCE();
  ScratchDir out;
  const auto files = damaged_files();
  const RunResult r = run_ssdo("process" + quoted_list(files) + " -o " + out.path.string() +
                               " --frame-timeout 5 --memory-limit 1024 --jobs 2 --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 1) << r.output.substr(0, 4000);
  EXPECT_NE(r.output.find("done 0, skipped 0, failed 185"), std::string::npos) << r.output.substr(r.output.size() - 500);
  for (const auto& f : files)
    EXPECT_NE(r.output.find(f.filename().string() + ": FAILED: "), std::string::npos) << f;
  // With a channel mapping more of them reach pixel decoding (and the memory limit).
  const RunResult mapped = run_ssdo("process" + quoted_list(files) + " -o " + out.path.string() +
                                    " --frame-timeout 5 --memory-limit 1024 --jobs 2 --terms ao --preset low "
                                    "--map depth=Y --fov 60 --force");
  EXPECT_EQ(mapped.exit_code, 1);
  EXPECT_NE(mapped.output.find(", failed "), std::string::npos);
  EXPECT_EQ(count_occurrences(mapped.output, ": FAILED: ") + count_occurrences(mapped.output, ": ok ("), 185);
}

// -v gives the batch's plan (a lone frame gets one worker, whatever --jobs asks), each
// frame's stages as the worker measured them, its peak memory and the page faults it took
// (a lone frame touches all of its memory fresh: some faults, however large the pages).
TEST(Batch, VerboseLinesGiveStagesMemoryAndPageFaults) {
  ScratchDir dir;
  copy_example("cornell", dir.path, "a");
  const RunResult r =
      run_ssdo("process " + dir / "a.exr" + " -o " + dir / "out" + " --terms ao --preset low --jobs 2 --threads 1 -v");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ssdo process: 1 frame, 1 worker process x 1 thread\n"), std::string::npos) << r.output;
  std::smatch m;
  const std::regex line(
      R"(read ([0-9.]+) ms, compute ([0-9.]+) ms, write ([0-9.]+) ms, worker ([0-9.]+) ms, isolation [0-9.]+ ms, )"
      R"(worker peak RSS ([0-9]+) MiB, ([0-9]+) page faults)");
  ASSERT_TRUE(std::regex_search(r.output, m, line)) << r.output;
  for (int stage = 1; stage <= 3; ++stage) EXPECT_GT(std::stod(m[stage].str()), 0.0) << m[0];
  EXPECT_GE(std::stod(m[4].str()), std::stod(m[1].str()) + std::stod(m[2].str()) + std::stod(m[3].str())) << m[0];
  EXPECT_GT(std::stoi(m[5].str()), 0) << m[0];
  EXPECT_GT(std::stoi(m[6].str()), 0) << m[0];
}

TEST(Batch, StalledAndOversizedFramesAreThatFramesErrors) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  for (const char* n : {"a", "b", "c"}) copy_example("cornell", dir.path / "in", n);
  // A stall: --frame-timeout shorter than the slow oracle needs.
  RunResult r = run_ssdo("process " + dir / "in/a.exr" + " -o " + dir / "out" +
                         " --method raymarch --preset ultra --frame-timeout 0.3 --jobs 1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("timed out after"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("s of CPU time"), std::string::npos) << r.output;  // computing, or waiting
  // Memory: a limit the frame cannot fit in. A 3000 x 3000 depth-only frame: its G-buffer
  // (depth, reconstructed normals and positions) alone is over 300 MiB as float, above the
  // smallest limit, 256 MiB, whatever the worker's own footprint.
  if (!kMemoryLimitEnforced) GTEST_SKIP() << "sanitizer build: workers run without --memory-limit (service/build_features.h)";
  {
    const int side = 3000;
    OIIO::ImageSpec spec(side, side, 1, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"Z"};
    spec.attribute("compression", "zip");
    std::vector<float> depth(size_t(side) * side, 5.0f);
    auto out = OIIO::ImageOutput::create((dir.path / "big.exr").string());
    ASSERT_TRUE(out && out->open((dir.path / "big.exr").string(), spec) &&
                out->write_image(OIIO::TypeDesc::FLOAT, depth.data()) && out->close());
  }
  r = run_ssdo("process " + dir / "big.exr" + " -o " + dir / "out" +
               " --map depth=Z --fov 60 --terms all --memory-limit 256 --jobs 1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("memory"), std::string::npos) << r.output;
}

TEST(Batch, AKilledWorkerFailsItsFrameTheOthersGoOn) {
  SSDO_REQUIRE_SHARED();
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  // a: a 1080p frame at the ultra preset (a second or more to read and compute, so the kill
  // below lands in it), b and c: small ones.
  fs::copy_file(shared_dir() / "gbuffers" / "perf1080.exr", dir.path / "in" / "a.exr");
  fs::copy_file(shared_dir() / "gbuffers" / "perf1080.camera.json", dir.path / "in" / "a.camera.json");
  copy_example("cornell", dir.path / "in", "b");
  copy_example("greeble", dir.path / "in", "c");
  // In sanitizer builds the runtime would catch the SIGSEGV and exit with status 1; the
  // worker must die by the signal, as in production. (Children read the options at start.)
  const std::string asan_options = std::getenv("ASAN_OPTIONS") ? std::getenv("ASAN_OPTIONS") : "";
  const ScopedVariable no_segv_handler("ASAN_OPTIONS", asan_options + ":handle_segv=0");
  SsdoProcess batch({"process", dir / "in", "-o", dir / "out", "--jobs", "1", "--terms", "ao", "--preset", "ultra"},
                    dir.path / "batch.log");
  ASSERT_TRUE(wait_until([&] { return !workers_of(batch.pid()).empty() || !batch.running(); }, 20));
  const auto workers = workers_of(batch.pid());
  ASSERT_FALSE(workers.empty()) << batch.log();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ::kill(workers.front(), SIGSEGV);  // as a segfault in a decoder would
  EXPECT_EQ(batch.signal_and_wait(0, 120), 1) << batch.log();
  const std::string log = batch.log();
  EXPECT_NE(log.find("a.exr: FAILED: worker killed by SIGSEGV"), std::string::npos) << log;
  EXPECT_NE(log.find("done 2, skipped 0, failed 1"), std::string::npos) << log;
  EXPECT_TRUE(exr_has_channel(dir / "out/b.ssdo.exr", "ao"));
}

// A frame replaced while the batch runs (a worker may have read it before the change) has
// its output marked out of date, said without -v: the rerun computes it again, the other
// frames are skipped.
TEST(Batch, AFrameReplacedWhileTheBatchRunsIsComputedAgainByTheRerun) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  for (int i = 0; i < 3; ++i) copy_example("cornell", dir.path / "in", numbered("f", i));
  const fs::path out = dir.path / "out";
  const std::vector<std::string> args = {"process", dir / "in", "-o", out.string(), "--jobs", "1", "--terms", "ao",
                                         "--views", "0", "--temporal", "0", "--preset", "low"};
  {
    SsdoProcess batch(args, dir.path / "batch1.log");
    {
      // While the first frame is in flight on the held worker.
      HeldWorkers held(batch.pid(), 1);
      ASSERT_TRUE(held.held()) << batch.log();
      copy_example("greeble", dir.path / "in", "f2.new");  // written aside, then renamed over f2
      fs::rename(dir.path / "in" / "f2.new.exr", dir.path / "in" / "f2.exr");
      fs::rename(dir.path / "in" / "f2.new.camera.json", dir.path / "in" / "f2.camera.json");
    }
    EXPECT_EQ(batch.signal_and_wait(0, 300), 0) << batch.log();
    EXPECT_NE(batch.log().find("changed while the batch ran"), std::string::npos) << batch.log();
  }
  SsdoProcess rerun(args, dir.path / "batch2.log");
  EXPECT_EQ(rerun.signal_and_wait(0, 300), 0) << rerun.log();
  EXPECT_NE(rerun.log().find("done 1, skipped 2"), std::string::npos) << rerun.log();
}

// A new version of a frame that fails does not leave the output of the old one beside its
// failure (it would pass for the frame's result), nor its previews; an output that is up to
// date stays when a forced recompute fails (a timeout: the output is still the frame's).
TEST(Batch, AFailedNewVersionOfAFrameRemovesTheOldOutputAForcedRecomputeKeepsACurrentOne) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "f");
  const std::string command = "process " + dir / "in" + " -o " + dir / "out" + " --terms ao --preset low --png";
  ASSERT_EQ(run_ssdo(command).exit_code, 0);
  ASSERT_TRUE(path_exists(dir.path / "out/f.ssdo.exr"));
  ASSERT_TRUE(path_exists(dir.path / "out/f.ssdo.ao.png"));
  const RunResult forced = run_ssdo(command + " --force --frame-timeout 0.001");
  EXPECT_EQ(forced.exit_code, 1) << forced.output;
  EXPECT_NE(forced.output.find("timed out"), std::string::npos) << forced.output;
  EXPECT_TRUE(path_exists(dir.path / "out/f.ssdo.exr")) << forced.output;
  const std::string good = read_text(dir.path / "in/f.exr");
  std::ofstream(dir.path / "in/f.exr", std::ios::binary | std::ios::trunc) << good.substr(0, good.size() / 2);
  const RunResult cut = run_ssdo(command);
  EXPECT_EQ(cut.exit_code, 1) << cut.output;
  EXPECT_NE(cut.output.find("its output of an earlier version of the frame"), std::string::npos) << cut.output;
  EXPECT_FALSE(path_exists(dir.path / "out/f.ssdo.exr")) << cut.output;
  EXPECT_FALSE(path_exists(dir.path / "out/f.ssdo.ao.png")) << cut.output;
}

// --png previews belong to their output: a rerun with --png computes a frame whose
// previews are not all there, and an output written without previews (or with other
// terms) removes the previews of an earlier run, which would pass for its pictures.
TEST(Batch, PreviewsMissingAreMadeAgainAndOldOnesDoNotOutliveTheirOutput) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "f");
  const std::string command = "process " + dir / "in" + " -o " + dir / "out" + " --preset low";
  ASSERT_EQ(run_ssdo(command + " --terms ao --png").exit_code, 0);
  const fs::path preview = dir.path / "out/f.ssdo.bent_normal.png";
  ASSERT_TRUE(path_exists(preview));
  fs::remove(preview);
  RunResult r = run_ssdo(command + " --terms ao --png");
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 output was missing some of their --png previews"), std::string::npos) << r.output;
  EXPECT_TRUE(path_exists(preview)) << r.output;
  EXPECT_NE(run_ssdo(command + " --terms ao --png").output.find("done 0, skipped 1"), std::string::npos);
  r = run_ssdo(command + " --terms ao");
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
  EXPECT_FALSE(path_exists(preview)) << r.output;
  EXPECT_FALSE(path_exists(dir.path / "out/f.ssdo.ao.png")) << r.output;
}

TEST(Batch, KillNineMidBatchThenRerunSkipsFinishedFramesLeavesNoPartialFile) {
  // The frames alone in time (f0..f7 are a sequence): the temporal window's resume is the
  // Temporal and Sequence tests'.
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  constexpr int kFrames = 8;
  for (int i = 0; i < kFrames; ++i) copy_example(i % 2 ? "greeble" : "cornell", dir.path / "in", numbered("f", i));
  const fs::path out = dir.path / "out";
  auto outputs = [&] {
    int n = 0;
    for (int i = 0; i < kFrames; ++i) n += path_exists(out / (numbered("f", i) + ".ssdo.exr"));
    return n;
  };
  int finished_before = 0;
  {
    SsdoProcess batch({"process", dir / "in", "-o", out.string(), "--jobs", "1", "--terms", "ao", "--preset", "low",
                       "--temporal", "0"},
                      dir.path / "batch1.log");
    ASSERT_TRUE(wait_until([&] { return outputs() >= 2; }, 120)) << batch.log();
    ASSERT_EQ(batch.signal_and_wait(SIGKILL, 10), 128 + SIGKILL);
    EXPECT_TRUE(wait_until([&] { return workers_of(batch.pid()).empty(); }, 10));
    finished_before = outputs();
  }
  ASSERT_LT(finished_before, kFrames) << "the batch finished before it was killed";
  const RunResult r =
      run_ssdo("process " + dir / "in" + " -o " + out.string() + " --jobs 2 --terms ao --preset low --temporal 0");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  char summary[64];
  std::snprintf(summary, sizeof summary, "done %d, skipped %d, failed 0", kFrames - finished_before, finished_before);
  EXPECT_NE(r.output.find(summary), std::string::npos) << r.output;
  EXPECT_EQ(outputs(), kFrames);
  for (int i = 0; i < kFrames; ++i) EXPECT_TRUE(exr_has_channel((out / (numbered("f", i) + ".ssdo.exr")).string(), "ao"));
  EXPECT_TRUE(temp_files(out).empty());
  // And once more: everything is skipped.
  const RunResult again =
      run_ssdo("process " + dir / "in" + " -o " + out.string() + " --terms ao --preset low --temporal 0");
  EXPECT_EQ(again.exit_code, 0);
  EXPECT_NE(again.output.find("done 0, skipped 8, failed 0"), std::string::npos) << again.output;
}

// A closed terminal's SIGHUP stops a batch as SIGINT and SIGTERM do (one test of the three
// signals in the code): the frame in flight finishes and is written whole, no new frame
// starts, exit 1; the workers ignore it. A frame is taken before its worker starts, so once
// the worker is there the first frame is in flight.
TEST(Batch, ASignalStopsTheBatchAfterTheFrameInFlight) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  constexpr int kFrames = 4;
  for (int i = 0; i < kFrames; ++i) copy_example("cornell", dir.path / "in", numbered("f", i));
  // The signal comes while the first frame is in flight on the held worker.
  auto batch_into = [&](const fs::path& out, const std::string& log) {
    return std::make_unique<SsdoProcess>(std::vector<std::string>{"process", dir / "in", "-o", out.string(), "--jobs",
                                                                  "1", "--terms", "ao", "--temporal", "0"},
                                         dir.path / log);
  };
  for (const int sig : {SIGHUP}) {
    const fs::path out = dir.path / ("out" + std::to_string(sig));
    const auto batch = batch_into(out, "batch" + std::to_string(sig) + ".log");
    {
      HeldWorkers held(batch->pid(), 1);
      ASSERT_TRUE(held.held()) << batch->log();
      ::kill(batch->pid(), sig);
      ASSERT_TRUE(batch->wait_for_log("ssdo process: stopping", 30)) << batch->log();
    }
    EXPECT_EQ(batch->signal_and_wait(0, 600), 1) << sig << "\n" << batch->log();
    EXPECT_NE(batch->log().find("ssdo process: stopping"), std::string::npos) << batch->log();
    int written = 0;
    for (int i = 0; i < kFrames; ++i) {
      const fs::path output = out / (numbered("f", i) + ".ssdo.exr");
      if (!path_exists(output)) continue;
      ++written;
      EXPECT_TRUE(exr_has_channel(output.string(), "ao")) << output;
    }
    EXPECT_GE(written, 1) << "the frame in flight finishes\n" << batch->log();
    EXPECT_LT(written, kFrames) << "no new frame starts\n" << batch->log();
    EXPECT_TRUE(temp_files(out).empty());
  }
  // A second signal stops at once: the frame in flight is abandoned, never half written.
  const fs::path out = dir.path / "out_twice";
  const auto batch = batch_into(out, "twice.log");
  HeldWorkers held(batch->pid(), 1);
  ASSERT_TRUE(held.held()) << batch->log();
  ::kill(batch->pid(), SIGINT);
  ASSERT_TRUE(wait_until([&] { return batch->log().find("a second signal stops at once") != std::string::npos; }, 30))
      << batch->log();
  EXPECT_EQ(batch->signal_and_wait(SIGINT, 30), 128 + SIGINT) << batch->log();
  EXPECT_NE(batch->log().find("stopped at once (a second signal)"), std::string::npos) << batch->log();
  EXPECT_FALSE(path_exists(out / (numbered("f", 0) + ".ssdo.exr"))) << batch->log();
}

// What a farm's file lists hold: one file under two spellings is one frame; a file whose
// name holds '#' is that file, not a pattern; a name with a newline keeps one line per
// frame in the log.
TEST(Batch, FileNamesAreTakenAsTheFilesTheyName) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "a");
  copy_example("cornell", dir.path / "in", "hash#1");
  copy_example("cornell", dir.path / "in", "two\nlines");
  const RunResult r = run_ssdo("process " + dir / "in/a.exr" + " " + dir / "in/../in/a.exr" + " '" +
                               dir / "in/hash#1.exr" + "' '" + dir / "in/two\nlines.exr" + "' -o " + dir / "out" +
                               " --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("done 3, skipped 0, failed 0"), std::string::npos) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "out/hash#1.ssdo.exr", "ao"));
  EXPECT_TRUE(exr_has_channel(dir / "out/two\nlines.ssdo.exr", "ao"));
  EXPECT_NE(r.output.find("two\\nlines.exr -> "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("two\nlines"), std::string::npos) << r.output;
}

// An input folder without frames fails the task (a share not mounted on a farm node); a
// chunk of a shot that gets none of its frames does not.
TEST(Batch, NoFramesInTheInputsIsAnErrorAnEmptyChunkIsNot) {
  ScratchDir dir;
  fs::create_directories(dir.path / "empty");
  RunResult r = run_ssdo("process " + dir / "empty" + " -o " + dir / "out");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("no frames (*.exr) in the inputs"), std::string::npos) << r.output;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "a");
  r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" + " --chunk 1/2 --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("no frames to process in this chunk or range"), std::string::npos) << r.output;
}

TEST(Batch, ConfigFileGivesOptionsFlagsOverrideIt) {
  ScratchDir dir;
  std::ofstream(dir / "config.json") << R"({"terms": "ao,ssdo", "preset": "low", "method": "hbao", "compression": "piz"})";
  RunResult r = run_ssdo("process " + example_frame("cornell.exr") + " -o " + dir / "out" + " --config " +
                         dir / "config.json" + " --terms ao");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "out/cornell.ssdo.exr", "ao"));
  EXPECT_FALSE(exr_has_channel(dir / "out/cornell.ssdo.exr", "ssdo_direct.R"));  // the flag won
  r = run_ssdo("process " + example_frame("cornell.exr") + " -o " + dir / "out2" + " --config " + dir / "config.json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "out2/cornell.ssdo.exr", "ssdo_direct.R"));  // the file's terms
  // Unknown keys and bad values are usage errors naming the key.
  std::ofstream(dir / "bad.json") << R"({"methd": "gtao"})";
  r = run_ssdo("process " + example_frame("cornell.exr") + " -o " + dir / "out3" + " --config " + dir / "bad.json");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("methd"), std::string::npos) << r.output;
  std::ofstream(dir / "bad2.json") << R"({"preset": "extreme"})";
  r = run_ssdo("process " + example_frame("cornell.exr") + " -o " + dir / "out3" + " --config " + dir / "bad2.json");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("preset"), std::string::npos) << r.output;
}

TEST(Batch, FramesAndChunkSelectThenRerunSkipsAndPlainLinesPerFrame) {
  ScratchDir dir;  // frames alone in time: --temporal 0
  for (int f = 1; f <= 10; ++f) {
    char stem[32];
    std::snprintf(stem, sizeof stem, "shot.%04d", f);
    copy_example("cornell", dir.path, stem);
  }
  const std::string pattern = dir / "shot.%04d.exr";
  // 1-10x3 = 1,4,7,10 plus 2 = 1,4,7,10,2; chunk 1/2 = the first 2 of 5 (floor(5/2)) = 1, 4.
  RunResult r = run_ssdo("process '" + pattern + "' --frames 1-10x3,2 --chunk 1/2 -o " + dir / "out" +
                         " --terms ao --preset low --temporal 0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> produced;
  for (const auto& e : fs::directory_iterator(dir.path / "out"))
    if (e.path().extension() == ".exr") produced.push_back(e.path().filename().string());
  std::sort(produced.begin(), produced.end());
  EXPECT_EQ(produced, (std::vector<std::string>{"shot.0001.ssdo.exr", "shot.0004.ssdo.exr"}));
  EXPECT_EQ(count_occurrences(r.output, ": ok ("), 2) << r.output;  // one plain line per frame
  EXPECT_NE(r.output.find("[2/2] "), std::string::npos) << r.output;
  r = run_ssdo("process '" + pattern + "' --frames 1-10x3,2 --chunk 2/2 -o " + dir / "out" +
               " --terms ao --preset low --temporal 0");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("done 3, skipped 0, failed 0"), std::string::npos) << r.output;
  r = run_ssdo("process '" + pattern + "' --frames 1-10x3,2 -o " + dir / "out" +
               " --terms ao --preset low --temporal 0");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("done 0, skipped 5, failed 0"), std::string::npos) << r.output;
  // Usage errors: 2, before any work.
  EXPECT_EQ(run_ssdo("process '" + pattern + "' --frames 1-x -o " + dir / "out").exit_code, 2);
  EXPECT_EQ(run_ssdo("process '" + pattern + "' -o " + dir / "out").exit_code, 2);
  EXPECT_EQ(run_ssdo("process '" + pattern + "' --frames 1 -o " + dir / "out" + " --jobs -1").exit_code, 2);
}

}  // namespace
}  // namespace ssdo::test
