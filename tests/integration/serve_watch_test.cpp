// `ssdo serve --watch`: the real service on a real folder, with inotify.
#include <atomic>
#include <fstream>
#include <thread>


#include "service_harness.h"

namespace ssdo::test {
namespace {

std::vector<std::string> serve_args(const ScratchDir& dir, const std::string& socket,
                                    std::vector<std::string> extra = {}, const std::string& preset = "low") {
  // Each frame alone in time: the watched sequences' temporal window is the Temporal tests'.
  std::vector<std::string> args = {"serve",    "--watch",          dir / "in",     "-o",     dir / "out",
                                   "--socket", socket,             "--terms",      "ao",     "--preset",
                                   preset,     "--frame-timeout",  kServiceFrameTimeoutS, "--memory-limit",
                                   "2048",     "--temporal",       "0"};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

// A frame written the way a slow renderer writes it: one open file, several writes with
// pauses, one close.
void write_slowly(const std::string& from, const fs::path& to) {
  const std::string bytes = read_text(from);
  std::ofstream out(to, std::ios::binary);
  const size_t piece = bytes.size() / 4 + 1;
  for (size_t at = 0; at < bytes.size(); at += piece) {
    out.write(bytes.data() + at, std::streamsize(std::min(piece, bytes.size() - at)));
    out.flush();
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
  }
}

// A valid EXR without depth: the frame has channels, not the ones a G-buffer needs.
void write_rgb_exr(const fs::path& path) {
  OIIO::ImageSpec spec(8, 8, 3, OIIO::TypeDesc::HALF);
  std::vector<float> pixels(8 * 8 * 3, 0.5f);
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out && out->open(path.string(), spec));
  out->write_image(OIIO::TypeDesc::FLOAT, pixels.data());
  out->close();
}

TEST(ServeWatch, TenFramesEachProcessedOnceBadOneGetsItsErrorFile) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const fs::path in = dir.path / "in", out = dir.path / "out";
  // Already there before the service starts.
  copy_example("cornell", in, "pre0");
  copy_example("greeble", in, "pre1");
  const std::string socket = socket_path_for("watch10");
  SsdoProcess service(serve_args(dir, socket), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();

  for (int i = 0; i < 5; ++i) copy_example(i % 2 ? "greeble" : "cornell", in, "drop" + std::to_string(i));
  // Written slowly in pieces: must not be read before it is closed.
  fs::copy_file(example_frame("cornell.camera.json"), in / "slow.camera.json");
  std::thread slow([&] { write_slowly(example_frame("cornell.exr"), in / "slow.exr"); });
  // Written under another name and renamed into place.
  fs::copy_file(example_frame("greeble.camera.json"), in / "moved.camera.json");
  fs::copy_file(example_frame("greeble.exr"), in / "moved.partial");
  fs::rename(in / "moved.partial", in / "moved.exr");
  // Corrupt: a truncated EXR.
  {
    const std::string bytes = read_text(example_frame("cornell.exr"));
    std::ofstream(in / "bad.exr", std::ios::binary).write(bytes.data(), 2000);
  }
  slow.join();

  const std::vector<std::string> good = {"pre0", "pre1", "drop0", "drop1", "drop2", "drop3", "drop4", "slow", "moved"};
  ASSERT_TRUE(wait_until(
      [&] {
        for (const auto& g : good)
          if (!path_exists(out / (g + ".ssdo.exr"))) return false;
        return path_exists(out / "bad.error.json");
      },
      120))
      << service.log();
  // Nothing left to do, nothing done twice.
  ASSERT_TRUE(wait_until(
      [&] {
        const json s = stats(socket);
        return s.value("queue_depth", 1) == 0 && s.value("in_flight", 1) == 0;
      },
      30));
  const std::string log = service.log();
  for (const auto& g : good) {
    EXPECT_EQ(count_occurrences(log, "ok " + (in / (g + ".exr")).string() + " ->"), 1) << g << "\n" << log;
    EXPECT_TRUE(exr_has_channel((out / (g + ".ssdo.exr")).string(), "ao")) << g;
    EXPECT_FALSE(path_exists(out / (g + ".error.json"))) << g;
  }
  EXPECT_EQ(count_occurrences(log, "FAILED " + (in / "bad.exr").string()), 1) << log;
  const json error = json::parse(read_text(out / "bad.error.json"), nullptr, false);
  ASSERT_TRUE(error.is_object());
  EXPECT_NE(error.value("error", "").find("bad.exr"), std::string::npos) << error.dump();
  EXPECT_FALSE(path_exists(out / "bad.ssdo.exr"));
  EXPECT_TRUE(temp_files(out).empty());

  const json s = stats(socket);
  EXPECT_EQ(s.value("frames_done", -1), 9) << s.dump();
  EXPECT_EQ(s.value("frames_failed", -1), 1) << s.dump();
  EXPECT_EQ(ping(socket).value("ok", false), true);

  // Graceful stop: exit 0, socket removed.
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0) << service.log();
  EXPECT_FALSE(path_exists(socket));
  EXPECT_TRUE(workers_of(service.pid()).empty());
}

TEST(ServeWatch, FailedFramesCorruptMissingChannelsEmptyDeletedReplaced) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  fs::create_directories(dir.path / "busy");
  const fs::path in = dir.path / "in", out = dir.path / "out";
  const std::string socket = socket_path_for("failures");
  // One worker, held while a frame asked over the socket is in flight, so that the watched
  // frames queue behind it and can be changed while queued.
  SsdoProcess service(serve_args(dir, socket, {"--jobs", "1", "--allow", dir / "busy"}), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  HeldWorkers held(service.pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  copy_example("cornell", dir.path / "busy", "busy");
  std::atomic<bool> busy_done{false};
  json busy_reply;
  std::thread busy([&] {
    Client c(socket);
    busy_reply = c.request({{"op", "process"}, {"input", dir / "busy/busy.exr"}});
    busy_done = true;
  });
  ASSERT_TRUE(wait_until([&] { return stats(socket).value("in_flight", 0) == 1; }, 20));

  std::ofstream(in / "corrupt.exr") << "this is not an EXR file";
  write_rgb_exr(in / "nodepth.exr");
  std::ofstream(in / "empty.exr").close();
  copy_example("cornell", in, "deleted");
  // Replaced while queued: a corrupt version first, then a good one renamed over it.
  std::ofstream(in / "replaced.exr") << "corrupt first version";
  fs::copy_file(example_frame("cornell.camera.json"), in / "replaced.camera.json");
  ASSERT_TRUE(wait_until([&] { return stats(socket).value("queue_depth", 0) == 5; }, 20)) << stats(socket).dump();
  fs::remove(in / "deleted.exr");
  fs::copy_file(example_frame("cornell.exr"), in / "replaced.partial");
  fs::rename(in / "replaced.partial", in / "replaced.exr");
  held.release();

  ASSERT_TRUE(wait_until(
      [&] {
        for (const char* n : {"corrupt", "nodepth", "empty", "deleted"})
          if (!path_exists(out / (std::string(n) + ".error.json"))) return false;
        return path_exists(out / "replaced.ssdo.exr") && busy_done;
      },
      120))
      << service.log();
  auto error_of = [&](const std::string& name) {
    return json::parse(read_text(out / (name + ".error.json")), nullptr, false).value("error", "");
  };
  EXPECT_NE(error_of("corrupt").find("not an OpenEXR file"), std::string::npos) << error_of("corrupt");
  EXPECT_NE(error_of("nodepth").find("depth"), std::string::npos) << error_of("nodepth");
  EXPECT_NE(error_of("empty").find("empty file"), std::string::npos) << error_of("empty");
  EXPECT_NE(error_of("deleted").find("deleted"), std::string::npos) << error_of("deleted");
  EXPECT_FALSE(path_exists(out / "replaced.error.json"));
  EXPECT_TRUE(exr_has_channel((out / "replaced.ssdo.exr").string(), "ao"));
  busy.join();
  EXPECT_EQ(busy_reply.value("ok", false), true) << busy_reply.dump();
  EXPECT_EQ(ping(socket).value("ok", false), true);

  // A failed frame rewritten correctly: processed, its error file removed.
  copy_example("cornell", in, "corrupt");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "corrupt.ssdo.exr") && !path_exists(out / "corrupt.error.json"); }, 60))
      << service.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// Whether a failed frame is tried again is decided from the failure, never from its
// message: a damaged frame whose name says "out of memory" fails once, for good.
TEST(ServeWatch, DamagedFrameNamedOutOfMemoryIsNotRetried) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const fs::path in = dir.path / "in", out = dir.path / "out";
  const std::string socket = socket_path_for("oom-name");
  SsdoProcess service(serve_args(dir, socket, {"--retries", "2"}), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  fs::copy_file(example_frame("cornell.camera.json"), in / "out of memory.camera.json");
  {
    // Headers whole, pixels cut short.
    const std::string frame = read_text(example_frame("cornell.exr"));
    std::ofstream(in / "out of memory.partial", std::ios::binary) << frame.substr(0, 30000);
  }
  fs::rename(in / "out of memory.partial", in / "out of memory.exr");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "out of memory.error.json"); }, 60)) << service.log();
  const json error = json::parse(read_text(out / "out of memory.error.json"), nullptr, false);
  EXPECT_NE(error.value("error", "").find("damaged or truncated file"), std::string::npos) << error.dump();
  EXPECT_FALSE(error.value("retry", true)) << error.dump();
  EXPECT_EQ(stats(socket).value("frames_retried", -1), 0) << service.log();
  EXPECT_EQ(service.log().find("retrying"), std::string::npos) << service.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

TEST(ServeWatch, PollFindsFramesWithoutEvents) {
  // --poll: frames that inotify does not report (as on network file systems) are found
  // by rescanning.
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("poll");
  SsdoProcess service(serve_args(dir, socket, {"--poll", "0.2"}), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  // A hard link made in the watched folder creates no IN_CLOSE_WRITE / IN_MOVED_TO event
  // (only IN_CREATE): only a rescan can find it.
  fs::create_directories(dir.path / "elsewhere");
  copy_example("cornell", dir.path / "elsewhere", "linked");
  fs::copy_file(example_frame("cornell.camera.json"), dir.path / "in" / "linked.camera.json");
  fs::create_hard_link(dir.path / "elsewhere" / "linked.exr", dir.path / "in" / "linked.exr");
  EXPECT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "linked.ssdo.exr"); }, 60)) << service.log();
}

// A symbolic link made in the watched folder is complete when made (no close to wait for):
// its frame is computed without a rescan.
// Links, symbolic or hard (an atomic publish: `ln stage/x.exr watch/x.exr`), are complete
// when made: no close follows them.
TEST(ServeWatch, ALinkMadeInTheFolderIsComputed) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("symlink");
  // --fov: the link needs no sidecar of its own, whose arrival would queue it too.
  SsdoProcess service(serve_args(dir, socket, {"--fov", "60"}), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  copy_example("cornell", dir.path / "in", "real");
  ASSERT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "real.ssdo.exr"); }, 60)) << service.log();
  fs::create_symlink("real.exr", dir.path / "in" / "alias.exr");
  EXPECT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "alias.ssdo.exr"); }, 60)) << service.log();
  fs::create_hard_link(dir.path / "in" / "real.exr", dir.path / "in" / "hard.exr");
  EXPECT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "hard.ssdo.exr"); }, 60)) << service.log();
  // A link to nothing is said to be one.
  fs::create_symlink("missing.exr", dir.path / "in" / "dangling.exr");
  ASSERT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "dangling.error.json"); }, 60)) << service.log();
  const json error = json::parse(read_text(dir.path / "out" / "dangling.error.json"), nullptr, false);
  EXPECT_NE(error.value("error", "").find("dangling.exr: a symbolic link to a missing file (missing.exr)"),
            std::string::npos)
      << error.dump();
}

TEST(ServeWatch, PoisonFramesEachGetAnErrorAndTheServiceStaysUp) {
  SSDO_REQUIRE_CONFORMANCE();
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const fs::path in = dir.path / "in", out = dir.path / "out";
  const std::string socket = socket_path_for("poisonwatch");
  SsdoProcess service(serve_args(dir, socket, {"--memory-limit", "1024", "--jobs", "2"}),
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  const auto files = damaged_files();
  ASSERT_EQ(files.size(), 185u);
  for (const fs::path& f : files) {
    fs::copy_file(f, in / (f.filename().string() + ".partial"));
    fs::rename(in / (f.filename().string() + ".partial"), in / (f.filename().string() + ".exr"));
  }
  auto error_files = [&] {
    int n = 0;
    for (const fs::path& f : files) n += path_exists(out / (f.filename().string() + ".error.json"));
    return n;
  };
  EXPECT_TRUE(wait_until([&] { return error_files() == int(files.size()); }, 300)) << error_files();
  EXPECT_EQ(ping(socket).value("ok", false), true);
  EXPECT_TRUE(service.running());
  copy_example("cornell", in, "good_after_poison");
  EXPECT_TRUE(wait_until([&] { return path_exists(out / "good_after_poison.ssdo.exr"); }, 60)) << service.log();
  EXPECT_TRUE(exr_has_channel((out / "good_after_poison.ssdo.exr").string(), "ao"));
  const json s = stats(socket);
  EXPECT_EQ(s.value("frames_failed", 0), int(files.size())) << s.dump();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// A restart with other options computes the watched frames again: their outputs' headers
// name the options they were made with (a restart with the same ones rewrites nothing:
// KillNineThenRestartProcessesEveryFrameExactlyOnce).
TEST(ServeWatch, ARestartWithOtherOptionsComputesTheFramesAgain) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "a");
  const fs::path output = dir.path / "out" / "a.ssdo.exr";
  const std::string socket = socket_path_for("reopts");
  auto radius = [&] {
    auto in = OIIO::ImageInput::open(output.string());
    if (!in) return -1.0;
    const json options = json::parse(in->spec().get_string_attribute("ssdo/options"), nullptr, false);
    return options.is_object() ? options.value("radius", -1.0) : -1.0;
  };
  {
    SsdoProcess service(serve_args(dir, socket), dir.path / "serve1.log");
    ASSERT_TRUE(wait_until([&] { return path_exists(output); }, 60)) << service.log();
    EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
  }
  EXPECT_EQ(radius(), 0.0);  // the frame's own radius
  SsdoProcess service(serve_args(dir, socket, {"--radius", "0.25"}), dir.path / "serve2.log");
  // The output is renamed into place before the frame's log line is written.
  const std::string ok = "ok " + (dir.path / "in" / "a.exr").string() + " ->";
  ASSERT_TRUE(wait_until([&] { return radius() == 0.25 && service.log().find(ok) != std::string::npos; }, 60))
      << service.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// A socket request with options no frame of the watch folder is computed with fails a
// watched frame (its output removed, an error file written): the watch's next start
// computes the frame again with its own options instead of taking that error as final.
// (A service without the watch fails it: a watching one would compute it again at once.)
TEST(ServeWatch, AFrameFailedByARequestsOtherOptionsIsComputedAgainByTheWatch) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "a");
  const fs::path input = dir.path / "in" / "a.exr", output = dir.path / "out" / "a.ssdo.exr";
  const std::string socket = socket_path_for("reqfail");
  const std::vector<std::string> allow = {"--allow", dir / "in"};
  {
    std::vector<std::string> args = serve_args(dir, socket, allow);
    args.erase(args.begin() + 1, args.begin() + 3);  // "--watch", DIR
    SsdoProcess service(args, dir.path / "serve1.log");
    ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
    Client c(socket);
    EXPECT_EQ(c.request({{"op", "process"}, {"input", input.string()}}).value("ok", false), true);
    EXPECT_TRUE(path_exists(output));
    const json r = c.request({{"op", "process"}, {"input", input.string()}, {"options", {{"part", "nope"}}}});
    EXPECT_EQ(r.value("code", ""), "frame_failed") << r.dump();
    EXPECT_FALSE(path_exists(output));
    EXPECT_TRUE(path_exists(dir.path / "out" / "a.error.json"));
    EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
  }
  SsdoProcess service(serve_args(dir, socket, allow), dir.path / "serve2.log");
  EXPECT_TRUE(wait_until([&] { return path_exists(output); }, 60)) << service.log();
  EXPECT_TRUE(wait_until([&] { return !path_exists(dir.path / "out" / "a.error.json"); }, 10)) << service.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// The same while the service runs: a socket request that replaces a watched frame's output
// with other options' (stand-in data), or fails it (the output removed, an error file
// written), queues the frame again, and the watch computes it with its own options.
TEST(ServeWatch, AWatchedFrameARequestReplacedOrFailedIsComputedAgainWhileTheServiceRuns) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "a");
  const fs::path input = dir.path / "in" / "a.exr", output = dir.path / "out" / "a.ssdo.exr";
  const fs::path error_file = dir.path / "out" / "a.error.json";
  const std::string socket = socket_path_for("reqredo");
  SsdoProcess service(serve_args(dir, socket, {"--allow", dir / "in", "--jobs", "1"}), dir.path / "serve.log");
  auto made_with = [&] {
    auto in = OIIO::ImageInput::open(output.string());
    return in ? std::string(in->spec().get_string_attribute("ssdo/options")) : std::string();
  };
  ASSERT_TRUE(wait_until([&] { return !made_with().empty(); }, 60)) << service.log();
  const std::string watch_options = made_with();
  Client c(socket);
  const json stand_in = c.request({{"op", "process"}, {"input", input.string()}, {"options", {{"io-only", true}}}});
  ASSERT_EQ(stand_in.value("ok", false), true) << stand_in.dump();
  EXPECT_TRUE(wait_until([&] { return made_with() == watch_options; }, 60)) << service.log();
  const json failed = c.request({{"op", "process"}, {"input", input.string()}, {"options", {{"part", "nope"}}}});
  ASSERT_EQ(failed.value("code", ""), "frame_failed") << failed.dump();
  EXPECT_TRUE(wait_until([&] { return made_with() == watch_options && !path_exists(error_file); }, 60))
      << service.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// The output folder is the watched folder: what the socket's requests write there (outputs,
// error files) is never taken for a frame. An output named as a frame would be (the watch
// reads every EXR but NAME.ssdo.exr), so such a name is refused before any work.
TEST(ServeWatch, OutputsWrittenIntoTheWatchedFolderAreNeverTakenForFrames) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "a");
  const std::string socket = socket_path_for("outinwatch");
  std::vector<std::string> args = serve_args(dir, socket, {"--jobs", "1"});
  args[4] = dir / "in";  // -o: the watched folder
  SsdoProcess service(args, dir.path / "serve.log");
  ASSERT_TRUE(wait_until([&] { return path_exists(dir.path / "in" / "a.ssdo.exr"); }, 60)) << service.log();
  const std::string input = dir / "in/a.exr";
  Client c(socket);
  const json as_frame = c.request({{"op", "process"}, {"input", input}, {"output", "result.exr"}});
  EXPECT_EQ(as_frame.value("code", ""), "bad_request") << as_frame.dump();
  EXPECT_NE(as_frame.value("error", "").find("result.ssdo.exr"), std::string::npos) << as_frame.dump();
  const json as_output = c.request({{"op", "process"}, {"input", input}, {"output", "result.ssdo.exr"}});
  EXPECT_EQ(as_output.value("ok", false), true) << as_output.dump();
  // A request that fails writes its error file beside the output.
  const json failed = c.request({{"op", "process"}, {"input", input}, {"output", "broken.ssdo.exr"},
                                 {"options", {{"part", "nope"}}}});
  EXPECT_EQ(failed.value("code", ""), "frame_failed") << failed.dump();
  ASSERT_TRUE(path_exists(dir.path / "in" / "broken.error.json"));
  ASSERT_TRUE(wait_until([&] {
    const json s = stats(socket);
    return s.value("queue_depth", 1) == 0 && s.value("in_flight", 1) == 0;
  }, 60));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // room for any late event
  EXPECT_FALSE(path_exists(dir.path / "in" / "result.exr"));
  const json s = stats(socket);
  EXPECT_EQ(s.value("frames_failed", -1), 1) << s.dump() << service.log();  // the broken request only
  EXPECT_EQ(count_occurrences(service.log(), "FAILED"), 1) << service.log();
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir.path / "in")) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  const std::vector<std::string> expected = {".ssdo-serve.lock", ".ssdo-spool",     "a.camera.json",   "a.exr",
                                             "a.ssdo.exr",       "broken.error.json", "result.ssdo.exr"};
  EXPECT_EQ(names, expected);
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// A frame rewritten while it is computed: the output of the old version is dated back
// behind the new one, so a service killed before the new version's turn computes the frame
// again when restarted instead of keeping the old version's output as up to date.
TEST(ServeWatch, AFrameRewrittenWhileComputedIsNotLeftUpToDateWithTheOldVersion) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  fs::copy_file(example_frame("cornell.camera.json"), dir.path / "in" / "a.camera.json");
  const fs::path input = dir.path / "in" / "a.exr", output = dir.path / "out" / "a.ssdo.exr";
  const std::string socket = socket_path_for("rewrite");
  // A second per frame: the rewrite comes while the first version is computed.
  const std::vector<std::string> slow = {"--jobs", "1", "--method", kSecondFrame.method};
  {
    SsdoProcess service(serve_args(dir, socket, slow, kSecondFrame.preset), dir.path / "serve1.log");
    ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
    fs::copy_file(example_frame("cornell.exr"), input);
    ASSERT_TRUE(wait_until([&] { return stats(socket).value("in_flight", 0) == 1; }, 30)) << service.log();
    // Often within the clock tick of the first version: the same file times.
    fs::copy_file(example_frame("cornell.exr"), dir.path / "in" / ".a.exr.part");
    fs::rename(dir.path / "in" / ".a.exr.part", input);
    ASSERT_TRUE(service.wait_for_log("changed while processing, queued again: " + input.string(), 600))
        << service.log();
    service.kill_now();  // before the new version's turn ends
  }
  ASSERT_TRUE(path_exists(output));
  EXPECT_LT(fs::last_write_time(output), fs::last_write_time(input)) << read_text(dir.path / "serve1.log");
  SsdoProcess service(serve_args(dir, socket, slow, kSecondFrame.preset), dir.path / "serve2.log");
  ASSERT_TRUE(service.wait_for_log("ok " + input.string() + " ->", 120)) << service.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
  EXPECT_GE(fs::last_write_time(output), fs::last_write_time(input));
}

// A watched frame found up to date at start still owns its output: a socket request for
// another frame of the same name is told of the conflict, and the output stays this one's.
TEST(ServeWatch, AFrameUpToDateAtStartKeepsItsOutputFromSocketRequests) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  fs::create_directories(dir.path / "allow");
  copy_example("cornell", dir.path / "in", "x");
  copy_example("greeble", dir.path / "allow", "x");
  const fs::path output = dir.path / "out" / "x.ssdo.exr";
  const std::string socket = socket_path_for("owned");
  const std::vector<std::string> allow = {"--allow", dir / "allow"};
  {
    SsdoProcess service(serve_args(dir, socket, allow), dir.path / "serve1.log");
    ASSERT_TRUE(wait_until([&] { return path_exists(output); }, 60)) << service.log();
    EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
  }
  const std::string before = exr_content(output.string());
  SsdoProcess service(serve_args(dir, socket, allow), dir.path / "serve2.log");
  ASSERT_TRUE(wait_until([&] { return stats(socket).value("frames_skipped", 0) == 1; }, 60)) << service.log();
  Client client(socket);
  const json r = client.request({{"op", "process"}, {"input", dir / "allow/x.exr"}});
  EXPECT_EQ(r.value("code", ""), "conflict") << r.dump();
  EXPECT_EQ(exr_content(output.string()), before);
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// frames_skipped counts a frame found up to date once (per version of it), not at every
// rescan, and not at all when this run computed it.
TEST(ServeWatch, ARescanDoesNotCountAnUpToDateFrameAgain) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_example("cornell", dir.path / "in", "before");
  const std::string socket = socket_path_for("skipcount");
  {
    SsdoProcess service(serve_args(dir, socket), dir.path / "serve1.log");
    ASSERT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "before.ssdo.exr"); }, 60)) << service.log();
    EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
  }
  SsdoProcess service(serve_args(dir, socket, {"--poll", "0.2"}), dir.path / "serve2.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  copy_example("greeble", dir.path / "in", "during");
  // The copy is not atomic: the watch may take the frame half written, see it change and
  // compute it again, so its output can exist before the frame is done.
  ASSERT_TRUE(wait_until(
      [&] {
        const json s = stats(socket);
        return s.value("frames_done", 0) == 1 && s.value("in_flight", 1) == 0 && s.value("queue_depth", 1) == 0;
      },
      60))
      << service.log();
  std::this_thread::sleep_for(std::chrono::seconds(2));  // ten rescans
  const json s = stats(socket);
  EXPECT_EQ(s.value("frames_skipped", -1), 1) << s.dump();
  EXPECT_EQ(s.value("frames_done", -1), 1) << s.dump();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// A frame whose error file cannot be written (its name is longer than a file name may be):
// the log says so instead of naming a file that is not there, and rescans do not compute
// the frame again (its failure is remembered while the service runs).
TEST(ServeWatch, AFailureWhoseErrorFileCannotBeWrittenIsSaidAndNotRetried) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("longname");
  SsdoProcess service(serve_args(dir, socket, {"--poll", "0.2"}), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  const fs::path input = dir.path / "in" / (std::string(246, 'b') + ".exr");  // NAME.error.json: 257 bytes
  std::ofstream(input) << "this is not an EXR file";
  const std::string failed = "FAILED " + input.string() + ": ";
  ASSERT_TRUE(service.wait_for_log(failed, 60)) << service.log();
  std::this_thread::sleep_for(std::chrono::seconds(2));  // ten rescans
  const std::string log = service.log();
  EXPECT_EQ(count_occurrences(log, failed), 1) << log;
  EXPECT_EQ(log.find(".error.json)"), std::string::npos) << log;
  EXPECT_NE(log.find("the error file could not be written"), std::string::npos) << log;
  EXPECT_EQ(stats(socket).value("frames_failed", -1), 1);
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

// A watch without a socket: frames computed, and no spool for inline frames it cannot get.
TEST(ServeWatch, AWatchAloneNeedsNoSocketAndMakesNoSpool) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  SsdoProcess service({"serve", "--watch", dir / "in", "-o", dir / "out", "--terms", "ao", "--preset", "low"},
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  copy_example("cornell", dir.path / "in", "a");
  EXPECT_TRUE(wait_until([&] { return path_exists(dir.path / "out" / "a.ssdo.exr"); }, 60)) << service.log();
  EXPECT_FALSE(path_exists(dir.path / "out" / ".ssdo-spool"));
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0) << service.log();
}

TEST(ServeWatch, KillNineThenRestartProcessesEveryFrameExactlyOnce) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const fs::path in = dir.path / "in", out = dir.path / "out";
  constexpr int kFrames = 8;
  for (int i = 0; i < kFrames; ++i) copy_example(i % 2 ? "greeble" : "cornell", in, numbered("f", i));
  auto outputs = [&] {
    int n = 0;
    for (int i = 0; i < kFrames; ++i) n += path_exists(out / (numbered("f", i) + ".ssdo.exr"));
    return n;
  };
  const std::string socket = socket_path_for("kill9");
  struct Stamp {
    fs::file_time_type time;
    ino_t inode;
  };
  std::map<std::string, Stamp> before;
  {
    SsdoProcess service(serve_args(dir, socket, {"--jobs", "1"}), dir.path / "serve1.log");
    ASSERT_TRUE(wait_until([&] { return outputs() >= 2; }, 120)) << service.log();
    ASSERT_EQ(service.signal_and_wait(SIGKILL, 10), 128 + SIGKILL);
    // Its workers die with it.
    EXPECT_TRUE(wait_until([&] { return workers_of(service.pid()).empty(); }, 10));
    for (int i = 0; i < kFrames; ++i) {
      const fs::path p = out / (numbered("f", i) + ".ssdo.exr");
      struct stat st {};
      if (::stat(p.c_str(), &st) == 0) before[p.string()] = {fs::last_write_time(p), st.st_ino};
    }
  }
  ASSERT_LT(int(before.size()), kFrames) << "the service finished before it was killed";
  SsdoProcess service(serve_args(dir, socket, {"--jobs", "1"}), dir.path / "serve2.log");
  ASSERT_TRUE(wait_until([&] { return outputs() == kFrames; }, 120)) << service.log();
  ASSERT_TRUE(wait_until(
      [&] {
        const json s = stats(socket);
        return s.value("queue_depth", 1) == 0 && s.value("in_flight", 1) == 0;
      },
      30));
  const std::string log = service.log();
  for (int i = 0; i < kFrames; ++i) {
    const fs::path p = out / (numbered("f", i) + ".ssdo.exr");
    EXPECT_TRUE(exr_has_channel(p.string(), "ao")) << p;
    const int runs = count_occurrences(log, "ok " + (in / (numbered("f", i) + ".exr")).string() + " ->");
    if (before.count(p.string())) {
      struct stat st {};
      ::stat(p.c_str(), &st);
      EXPECT_EQ(st.st_ino, before[p.string()].inode) << p << " was rewritten";
      EXPECT_EQ(fs::last_write_time(p), before[p.string()].time) << p << " was rewritten";
      EXPECT_EQ(runs, 0) << p;
    } else {
      EXPECT_EQ(runs, 1) << p << "\n" << log;
    }
  }
  EXPECT_TRUE(temp_files(out).empty());
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0);
}

}  // namespace
}  // namespace ssdo::test
