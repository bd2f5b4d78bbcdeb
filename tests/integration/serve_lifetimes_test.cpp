// `ssdo serve` over time and under load: retries of transient failures, sidecars that
// arrive late, a watch folder that is replaced, two instances side by side, and the
// limits that keep many or hostile clients from taking the service's memory, disk or
// connection slots.
#include <sys/file.h>
#include <sys/resource.h>

#include <atomic>
#include <fstream>
#include <thread>

#include "service/build_features.h"
#include "service_harness.h"

namespace ssdo::test {
namespace {

std::vector<std::string> watch_args(const fs::path& in, const fs::path& out, const std::string& socket,
                                    std::vector<std::string> extra = {}) {
  std::vector<std::string> args = {"serve", "--watch", in.string(), "-o", out.string(), "--socket", socket,
                                   "--terms", "ao", "--preset", "low", "--frame-timeout", kServiceFrameTimeoutS,
                                   "--memory-limit", "2048"};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

// The "watch" object of the service's stats (null when there is none).
json watch_stats(const std::string& socket) {
  const json s = stats(socket);
  return s.contains("watch") && s["watch"].is_object() ? s["watch"] : json::object();
}


// A service watching DIR/in (made empty) into DIR/out, with its socket; `ready` once it said so.
struct EmptyWatch {
  fs::path in, out;
  std::string socket;
  std::unique_ptr<SsdoProcess> service;
  bool ready = false;
  EmptyWatch(const ScratchDir& dir, const std::string& tag)
      : in(dir.path / "in"), out(dir.path / "out"), socket(socket_path_for(tag)) {
    fs::create_directories(in);
    service = std::make_unique<SsdoProcess>(watch_args(in, out, socket), dir.path / "serve.log");
    ready = service->wait_for_log("ready", 30);
  }
};

// --- 11: retries, late sidecars, error files ------------------------------------------

TEST(ServeLifetimes, SidecarArrivingAfterTheFrameRequeuesIt) {
  ScratchDir dir;
  EmptyWatch watch(dir, "sidecar");
  const fs::path &in = watch.in, &out = watch.out;
  SsdoProcess& service = *watch.service;
  ASSERT_TRUE(watch.ready) << service.log();
  fs::copy_file(example_frame("cornell.exr"), in / "late.exr");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "late.error.json"); }, 30)) << service.log();
  // The sidecar counts as new even when the clock does not say so: files written within
  // one clock tick share a time, here made certain by dating the error file ahead.
  fs::last_write_time(out / "late.error.json", fs::file_time_type::clock::now() + std::chrono::seconds(5));
  fs::copy_file(example_frame("cornell.camera.json"), in / "late.camera.json");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "late.ssdo.exr"); }, 30)) << service.log();
  EXPECT_TRUE(wait_until([&] { return !path_exists(out / "late.error.json"); }, 5));
  EXPECT_TRUE(exr_has_channel((out / "late.ssdo.exr").string(), "ao"));
}

// The failed version is in the error file, so a restarted service tells a sidecar that
// came while it was down from the one the failure saw, whatever the clock says.
TEST(ServeLifetimes, SidecarArrivingWhileTheServiceIsDownRequeuesTheFrameWhateverTheClock) {
  ScratchDir dir;
  const fs::path in = dir.path / "in", out = dir.path / "out";
  fs::create_directories(in);
  fs::copy_file(example_frame("cornell.exr"), in / "late.exr");
  {
    const std::string socket = socket_path_for("downside");
    SsdoProcess service(watch_args(in, out, socket), dir.path / "serve1.log");
    ASSERT_TRUE(wait_until([&] { return path_exists(out / "late.error.json"); }, 30)) << service.log();
  }
  const json error = json::parse(read_text(out / "late.error.json"));
  EXPECT_TRUE(error.contains("version")) << error.dump();
  fs::copy_file(example_frame("cornell.camera.json"), in / "late.camera.json");
  fs::last_write_time(out / "late.error.json", fs::file_time_type::clock::now() + std::chrono::seconds(5));
  const std::string socket = socket_path_for("downside2");
  SsdoProcess service(watch_args(in, out, socket), dir.path / "serve2.log");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "late.ssdo.exr"); }, 30)) << service.log();
  EXPECT_TRUE(wait_until([&] { return !path_exists(out / "late.error.json"); }, 5));
}

TEST(ServeLifetimes, ErrorFileOlderThanTheSidecarDoesNotHideTheFrameAfterARestart) {
  ScratchDir dir;
  const fs::path in = dir.path / "in", out = dir.path / "out";
  fs::create_directories(in);
  fs::create_directories(out);
  fs::copy_file(example_frame("cornell.exr"), in / "f.exr");
  // An earlier run failed the frame (no sidecar then); the sidecar came while it was down.
  std::ofstream(out / "f.error.json") << R"({"input": "x", "error": "no camera"})" << "\n";
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  fs::copy_file(example_frame("cornell.camera.json"), in / "f.camera.json");
  const std::string socket = socket_path_for("errold");
  SsdoProcess service(watch_args(in, out, socket), dir.path / "serve.log");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "f.ssdo.exr"); }, 30)) << service.log();
  // The stale error file goes once the output is in place (a moment after its rename).
  EXPECT_TRUE(wait_until([&] { return !path_exists(out / "f.error.json"); }, 5)) << service.log();
}

TEST(ServeLifetimes, NewerErrorRemovesTheStaleOutput) {
  ScratchDir dir;
  const fs::path in = dir.path / "in", out = dir.path / "out";
  fs::create_directories(in);
  copy_example("cornell", in, "f");
  const std::string socket = socket_path_for("stale");
  SsdoProcess service(watch_args(in, out, socket), dir.path / "serve.log");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "f.ssdo.exr"); }, 30)) << service.log();
  // A new version of the frame that cannot be read: the old output no longer describes it.
  {
    const std::string bytes = read_text(example_frame("cornell.exr"));
    std::ofstream(in / ".f.partial", std::ios::binary).write(bytes.data(), 2000);
  }
  fs::rename(in / ".f.partial", in / "f.exr");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "f.error.json"); }, 30)) << service.log();
  EXPECT_TRUE(wait_until([&] { return !path_exists(out / "f.ssdo.exr"); }, 5)) << service.log();
  const json error = json::parse(read_text(out / "f.error.json"));
  EXPECT_NE(error.value("error", "").find("truncated"), std::string::npos) << error.dump();
}

// The worker killed in the middle of a frame: the frame is computed again by a new worker.
TEST(ServeLifetimes, WorkerKilledMidFrameIsRetried) {
  ScratchDir dir;
  const fs::path in = dir.path / "in", out = dir.path / "out";
  fs::create_directories(in);
  const std::string socket = socket_path_for("retry");
  SsdoProcess service(watch_args(in, out, socket, {"--jobs", "1"}), dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  HeldWorkers held(service.pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  copy_example("cornell", in, "k");
  // The frame in flight on the held worker, which dies there.
  ASSERT_TRUE(wait_until([&] { return stats(socket).value("in_flight", 0) == 1; }, 20)) << service.log();
  ASSERT_EQ(::kill(held.pids()[0], SIGKILL), 0);
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "k.ssdo.exr"); }, 60)) << service.log();
  EXPECT_TRUE(exr_has_channel((out / "k.ssdo.exr").string(), "ao"));
  EXPECT_FALSE(path_exists(out / "k.error.json"));
  EXPECT_NE(service.log().find("retrying"), std::string::npos) << service.log();
  const std::vector<std::string> left = temp_files(out);
  EXPECT_TRUE(left.empty()) << left.front() << "\n" << service.log();
}

// --- 12: the watch folder replaced ----------------------------------------------------

TEST(ServeLifetimes, WatchFolderDeletedOrRenamedAndRecreatedIsWatchedAgain) {
  ScratchDir dir;
  EmptyWatch watch(dir, "rewatch");
  const fs::path &in = watch.in, &out = watch.out;
  const std::string& socket = watch.socket;
  SsdoProcess& service = *watch.service;
  ASSERT_TRUE(watch.ready) << service.log();
  EXPECT_EQ(watch_stats(socket).value("state", ""), "watching");

  fs::remove_all(in);
  ASSERT_TRUE(wait_until([&] { return watch_stats(socket).value("state", "") == "lost"; }, 5))
      << watch_stats(socket).dump() << service.log();
  fs::create_directories(in);
  ASSERT_TRUE(wait_until([&] { return watch_stats(socket).value("state", "") == "watching"; }, 5))
      << watch_stats(socket).dump() << service.log();
  copy_example("cornell", in, "a");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "a.ssdo.exr"); }, 30)) << service.log();

  fs::rename(in, dir.path / "in.old");
  fs::create_directories(in);
  ASSERT_TRUE(wait_until([&] { return watch_stats(socket).value("reestablished", 0) == 2; }, 5))
      << watch_stats(socket).dump() << service.log();
  copy_example("greeble", in, "b");
  ASSERT_TRUE(wait_until([&] { return path_exists(out / "b.ssdo.exr"); }, 30)) << service.log();
  // The renamed folder is no longer watched.
  copy_example("greeble", dir.path / "in.old", "c");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_FALSE(path_exists(out / "c.ssdo.exr"));
}

// --- 13: two instances ----------------------------------------------------------------

TEST(ServeLifetimes, StoppingOneInstanceLeavesTheOthersSocket) {
  ScratchDir dir;
  const std::string socket = socket_path_for("two");
  fs::create_directories(dir.path / "in");
  SsdoProcess first({"serve", "--socket", socket, "-o", dir / "out1", "--allow", dir / "in"}, dir.path / "1.log");
  ASSERT_TRUE(first.wait_for_log("ready", 30)) << first.log();
  fs::remove(socket);  // an operator reuses the path for a second instance
  SsdoProcess second({"serve", "--socket", socket, "-o", dir / "out2", "--allow", dir / "in"}, dir.path / "2.log");
  ASSERT_TRUE(second.wait_for_log("ready", 30)) << second.log();
  EXPECT_EQ(first.signal_and_wait(SIGTERM, 30), 0);
  EXPECT_TRUE(path_exists(socket));
  EXPECT_EQ(ping(socket).value("ok", false), true);
}

TEST(ServeLifetimes, SecondInstanceOnTheSameOutputFolderIsRefused) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  SsdoProcess first({"serve", "--socket", socket_path_for("lock1"), "-o", dir / "out", "--allow", dir / "in"},
                    dir.path / "1.log");
  ASSERT_TRUE(first.wait_for_log("ready", 30)) << first.log();
  ASSERT_TRUE(path_exists(dir.path / "out" / ".ssdo-spool"));
  SsdoProcess second({"serve", "--socket", socket_path_for("lock2"), "-o", dir / "out", "--allow", dir / "in"},
                     dir.path / "2.log");
  EXPECT_TRUE(wait_until([&] { return !second.running(); }, 10)) << second.log();
  EXPECT_EQ(second.signal_and_wait(SIGTERM, 10), 1) << second.log();
  EXPECT_NE(second.log().find("another ssdo serve"), std::string::npos) << second.log();
  EXPECT_TRUE(path_exists(dir.path / "out" / ".ssdo-spool"));
  EXPECT_EQ(ping(socket_path_for("lock1")).value("ok", false), true);
}

// A start that fails (here: the socket's folder is missing) leaves no output folder it made,
// and in a folder that was there, no spool.
TEST(ServeLifetimes, AFailedStartLeavesNoFolderItMade) {
  ScratchDir dir;
  const std::string socket = dir / "missing/s.sock";
  RunResult r = run_ssdo("serve --socket " + socket + " -o " + dir / "made/out");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--socket " + socket + ": No such file or directory"), std::string::npos) << r.output;
  EXPECT_FALSE(path_exists(dir.path / "made"));
  fs::create_directories(dir.path / "there");
  r = run_ssdo("serve --socket " + socket + " -o " + dir / "there");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(path_exists(dir.path / "there" / ".ssdo-spool"));
  EXPECT_TRUE(path_exists(dir.path / "there"));
}

// The output folder removed under a running service: made again and locked again, so its
// frames are written and a second instance is still refused.
TEST(ServeLifetimes, AnOutputFolderRemovedWhileRunningIsMadeAgainAndLocked) {
  ScratchDir dir;
  EmptyWatch watch(dir, "gone");
  const fs::path &in = watch.in, &out = watch.out;
  SsdoProcess& service = *watch.service;
  ASSERT_TRUE(watch.ready) << service.log();
  fs::remove_all(out);
  ASSERT_TRUE(service.wait_for_log("(or its lock) was removed: made again and locked", 30)) << service.log();
  copy_example("cornell", in, "f");
  EXPECT_TRUE(wait_until([&] { return path_exists(out / "f.ssdo.exr"); }, 60)) << service.log();
  SsdoProcess second({"serve", "--socket", socket_path_for("gone2"), "-o", out.string(), "--allow", in.string()},
                     dir.path / "2.log");
  EXPECT_TRUE(wait_until([&] { return !second.running(); }, 10)) << second.log();
  EXPECT_NE(second.log().find("another ssdo serve"), std::string::npos) << second.log();
  EXPECT_EQ(service.signal_and_wait(SIGTERM, 30), 0) << service.log();
}

// --- 14: the client's inline reply ----------------------------------------------------

TEST(ServeLifetimes, ClientRefusesAHugeInlineReply) {
  ScratchDir dir;
  const std::string socket = socket_path_for("liar");
  const int listener = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, socket.c_str(), sizeof addr.sun_path - 1);
  ::unlink(socket.c_str());
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(listener, 4), 0);
  std::thread liar([&] {
    const int fd = ::accept(listener, nullptr, nullptr);
    std::string request;
    if (read_message(fd, request, size_t(1) << 20, deadline_in(10)) == IoStatus::ok) {
      skip_bytes(fd, json::parse(request).value("inline_size", size_t(0)), deadline_in(10));
      write_message(fd, json{{"ok", true}, {"inline_size", uint64_t(1) << 62}}.dump(), deadline_in(10));
    }
    ::close(fd);
  });
  const RunResult r = run_ssdo("client --socket " + socket + " --inline -o " + (dir / "o") + " process " +
                               example_frame("cornell.exr"));
  liar.join();
  ::close(listener);
  ::unlink(socket.c_str());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("4611686018427387904"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--max-inline-mb"), std::string::npos) << r.output;
}

// --- 15: memory, disk and connection slots shared by many clients ---------------------

// Holds a connection that announced a header of `size` bytes and sent one byte of it.
int start_header(const std::string& socket, uint32_t size) {
  Client c(socket);
  if (!c.connected()) return -1;
  const int fd = ::dup(c.fd());
  unsigned char prefix[5];
  encode_length(size, prefix);
  prefix[4] = '{';
  write_all(fd, prefix, 5, deadline_in(5));
  return fd;
}

TEST(ServeLifetimes, HeaderBytesAcrossConnectionsAreBounded) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("hdr");
  SsdoProcess service({"serve", "--socket", socket, "-o", dir / "out", "--allow", dir / "in", "--max-request-bytes",
                       "65536", "--client-timeout", "10"},
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  std::vector<int> held;
  for (int i = 0; i < 16; ++i) held.push_back(start_header(socket, 65536));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // One more large header does not fit in the service's header memory: busy at once.
  const int extra = start_header(socket, 65536);
  std::string text;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(read_message(extra, text, size_t(1) << 20, deadline_in(5)), IoStatus::ok);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
  const json busy = json::parse(text);
  EXPECT_EQ(busy.value("code", ""), "busy") << text;
  EXPECT_NE(busy.value("error", "").find("request headers"), std::string::npos) << text;
  // Small requests still get through.
  EXPECT_EQ(ping(socket).value("ok", false), true);
  for (int fd : held) ::close(fd);
  ::close(extra);
}

TEST(ServeLifetimes, InlineUploadsShareABoundedSpool) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("spool");
  SsdoProcess service({"serve", "--socket", socket, "-o", dir / "out", "--allow", dir / "in", "--max-inline-mb", "2",
                       "--max-spool-mb", "3", "--client-timeout", "10"},
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  Client first(socket);
  ASSERT_TRUE(first.connected());
  const std::string header = json{{"op", "process"}, {"inline_size", 2 << 20}}.dump();
  ASSERT_EQ(write_message(first.fd(), header, deadline_in(5)), IoStatus::ok);
  const std::string part(1 << 20, 'x');  // half the payload: its spool bytes are taken
  ASSERT_EQ(write_all(first.fd(), part.data(), part.size(), deadline_in(5)), IoStatus::ok);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  Client second(socket);
  ASSERT_EQ(write_message(second.fd(), header, deadline_in(5)), IoStatus::ok);
  const json r = second.read_response(nullptr, 5);
  EXPECT_EQ(r.value("code", ""), "busy") << r.dump();
  EXPECT_NE(r.value("error", "").find("--max-spool-mb"), std::string::npos) << r.dump();
  // Larger than the whole spool (and within --max-inline-mb): never fits, so not "busy"
  // (try again) but a bad request.
  const std::string small_spool = socket_path_for("spool2");
  SsdoProcess other({"serve", "--socket", small_spool, "-o", dir / "out2", "--allow", dir / "in", "--max-inline-mb",
                     "8", "--max-spool-mb", "2"},
                    dir.path / "serve2.log");
  ASSERT_TRUE(other.wait_for_log("ready", 30)) << other.log();
  Client third(small_spool);
  const json big = third.request({{"op", "process"}, {"inline_size", 4 << 20}}, {}, nullptr, 5);
  EXPECT_EQ(big.value("code", ""), "bad_request") << big.dump();
  EXPECT_NE(big.value("error", "").find("larger than the whole spool"), std::string::npos) << big.dump();
}

TEST(ServeLifetimes, IdleConnectionsDoNotLockOthersOut) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("idle");
  SsdoProcess service({"serve", "--socket", socket, "-o", dir / "out", "--allow", dir / "in", "--max-clients", "4"},
                      dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  std::vector<std::unique_ptr<Client>> idle;
  for (int i = 0; i < 4; ++i) idle.push_back(std::make_unique<Client>(socket));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(ping(socket).value("ok", false), true);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
}

// A ping sent only once the service has had time to answer the connection at accept: a
// client that sends its request after a "busy" answer still reads that answer (the
// connection is not closed under its request).
json late_ping(const std::string& socket) {
  Client c(socket);
  if (!c.connected()) return {{"transport_error", "connect"}};
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  return c.request({{"op", "ping"}}, {}, nullptr, 10);
}

// A client the service cannot start a thread for (here: its address space capped just above
// what it maps, so no new thread gets a stack) is told so, even when it sends its request
// after the answer, and closed; the service goes on and serves the next client once threads
// start again.
TEST(ServeLifetimes, AClientWithoutAThreadIsRefusedAndTheServiceGoesOn) {
  if (!kMemoryLimitEnforced)
    GTEST_SKIP() << "sanitizer build: its runtime's own mappings fail under an address-space cap "
                    "(service/build_features.h)";
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  const std::string socket = socket_path_for("nothread");
  SsdoProcess service({"serve", "--socket", socket, "-o", dir / "out", "--allow", dir / "in"}, dir.path / "serve.log");
  ASSERT_TRUE(service.wait_for_log("ready", 30)) << service.log();
  rlimit old{};
  ASSERT_EQ(::prlimit(service.pid(), RLIMIT_AS, nullptr, &old), 0);
  // A thread may still start under the cap on a stack the C library kept from an ended one,
  // or where the service unmapped memory since its size was read: then the ping is served,
  // and the cap is tried again (the service before this change ended at the first refusal).
  json refused = json::object();
  for (int attempt = 0; attempt < 5 && refused.value("code", "") != "busy"; ++attempt) {
    const long mapped_kib = status_kib(service.pid(), "VmSize");
    ASSERT_GT(mapped_kib, 0);
    const rlimit capped{rlim_t(mapped_kib + 1024) * 1024, old.rlim_max};  // 1 MiB over: no 8 MiB stack
    ASSERT_EQ(::prlimit(service.pid(), RLIMIT_AS, &capped, nullptr), 0);
    refused = late_ping(socket);
    ASSERT_EQ(::prlimit(service.pid(), RLIMIT_AS, &old, nullptr), 0);
    ASSERT_TRUE(service.running()) << service.log();
  }
  EXPECT_EQ(refused.value("code", ""), "busy") << refused.dump();
  EXPECT_NE(refused.value("error", "").find("could not start a thread"), std::string::npos) << refused.dump();
  EXPECT_EQ(ping(socket).value("ok", false), true);
  // The refused client is not counted: only the stats request's own connection is, once the
  // pings' connections have closed.
  EXPECT_TRUE(wait_until([&] { return stats(socket).value("clients", -1) == 1; }, 10));
}

// --- 16: memory estimated from the header; one pixel limit ------------------------------

// 8208 x 8208 (just over 2^26 pixels), three half channels of zeros, ZIP: a few hundred KB
// that decode to 385 MiB. Written once per test program (it takes seconds).
const fs::path& zip_bomb() {
  static const struct File {
    fs::path path = fs::temp_directory_path() / ("ssdo_it_" + std::to_string(::getpid()) + "_bomb.exr");
    File() {
      constexpr int kSide = 8208;
      OIIO::ImageSpec spec(kSide, kSide, 3, OIIO::TypeDesc::HALF);
      spec.channelnames = {"Z", "N.X", "N.Y"};
      spec.attribute("compression", "zip");
      auto out = OIIO::ImageOutput::create(path.string());
      if (!out || !out->open(path.string(), spec)) return;
      const std::vector<uint16_t> rows(size_t(kSide) * 3 * 16, 0);
      for (int y = 0; y < kSide; y += 16)
        out->write_scanlines(y, std::min(y + 16, kSide), 0, OIIO::TypeDesc::HALF, rows.data());
      out->close();
    }
    ~File() { fs::remove(path); }
  } file;
  return file.path;
}

TEST(ServeLifetimes, DecodeLargerThanTheMemoryLimitIsRefusedWithTheReason) {
  ScratchDir dir;
  const RunResult r = run_ssdo("process " + zip_bomb().string() + " -o " + (dir / "out") +
                               " --memory-limit 1024 --max-pixels 70000000");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.output.find("damaged or truncated"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("needs an estimated"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1024 MiB"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--memory-limit"), std::string::npos) << r.output;
}

TEST(ServeLifetimes, InfoAndProcessShareThePixelLimit) {
  ScratchDir dir;
  const RunResult info = run_ssdo("info " + zip_bomb().string());
  const RunResult process = run_ssdo("process " + zip_bomb().string() + " -o " + (dir / "out"));
  EXPECT_NE(info.exit_code, 0) << info.output;
  EXPECT_NE(process.exit_code, 0) << process.output;
  EXPECT_NE(info.output.find("limit 67108864 pixels"), std::string::npos) << info.output;
  EXPECT_NE(process.output.find("limit 67108864 pixels"), std::string::npos) << process.output;
}

}  // namespace
}  // namespace ssdo::test
