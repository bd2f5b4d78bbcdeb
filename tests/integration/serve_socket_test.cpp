// `ssdo serve --socket`: the real service, real clients on a real Unix socket.
#include <poll.h>

#include <atomic>
#include <mutex>
#include <thread>

#include "service_harness.h"

namespace ssdo::test {
namespace {

struct SocketService {
  ScratchDir& dir;
  std::string socket;
  std::unique_ptr<SsdoProcess> process;
  SocketService(ScratchDir& d, const std::string& tag, std::vector<std::string> extra = {})
      : dir(d), socket(socket_path_for(tag)) {
    fs::create_directories(dir.path / "frames");
    copy_example("cornell", dir.path / "frames", "cornell");
    copy_example("greeble", dir.path / "frames", "greeble");
    std::vector<std::string> args = {"serve",  "--socket", socket,  "-o",       dir / "out", "--allow",
                                     dir / "frames", "--terms", "ao", "--preset", "low", "--frame-timeout", kServiceFrameTimeoutS,
                                     "--memory-limit", "2048"};
    args.insert(args.end(), extra.begin(), extra.end());
    process = std::make_unique<SsdoProcess>(args, dir.path / ("serve-" + tag + ".log"));
    ready = process->wait_for_log("ready", 30);
  }
  bool ready = false;
  std::string log() const { return process->log(); }
};

json process_path(const std::string& socket, const std::string& input, json extra = json::object()) {
  Client c(socket);
  json request{{"op", "process"}, {"input", input}};
  request.update(extra);
  return c.request(request);
}

long peak_rss_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

TEST(ServeSocket, SixteenClientsTwoRequestsEachByPathAndInline) {
  ScratchDir dir;
  SocketService service(dir, "sixteen");
  ASSERT_TRUE(service.ready) << service.log();
  struct stat st {};
  ASSERT_EQ(::stat(service.socket.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);

  const std::string frame_bytes = read_text(dir.path / "frames" / "cornell.exr");
  const json sidecar = json::parse(read_text(dir.path / "frames" / "cornell.camera.json"));
  constexpr int kClients = 16, kRequests = 2;  // one request by path and one inline per client
  // The fastest preset: what is tested is the service under concurrent clients, and each
  // request's own options reach its frame.
  const json options = {{"preset", "low"}};
  std::mutex mutex;
  std::vector<std::string> failures;
  std::atomic<int> answered{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      Client client(service.socket);  // one connection, several requests
      for (int r = 0; r < kRequests; ++r) {
        const std::string tag = "c" + std::to_string(c) + "_" + std::to_string(r);
        std::string problem;
        if ((c + r) % 2 == 0) {
          const std::string output = dir / ("out/" + tag + ".ssdo.exr");
          const json reply = client.request({{"op", "process"},
                                             {"id", tag},
                                             {"input", dir / ((c % 2) ? "frames/greeble.exr" : "frames/cornell.exr")},
                                             {"output", output},
                                             {"options", options}});
          if (!reply.value("ok", false) || reply.value("id", "") != tag || reply.value("output", "") != output ||
              !exr_has_channel(output, "ao"))
            problem = tag + " by path: " + reply.dump();
        } else {
          std::string bytes;
          const json reply = client.request(
              {{"op", "process"}, {"id", tag}, {"name", tag}, {"sidecar", sidecar}, {"reply", "inline"}, {"options", options}},
              frame_bytes, &bytes);
          const std::string saved = dir / ("inline_" + tag + ".exr");
          std::ofstream(saved, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
          if (!reply.value("ok", false) || reply.value("id", "") != tag || bytes.size() < 4 ||
              !exr_has_channel(saved, "ao_denoised"))
            problem = tag + " inline: " + reply.dump();
        }
        ++answered;
        if (!problem.empty()) {
          std::lock_guard<std::mutex> lock(mutex);
          failures.push_back(problem);
        }
      }
    });
  }
  for (auto& t : clients) t.join();
  EXPECT_EQ(answered.load(), kClients * kRequests);
  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, first: " << failures.front();
  const json s = stats(service.socket);
  EXPECT_EQ(s.value("frames_done", 0), kClients * kRequests) << s.dump();
  EXPECT_EQ(s.value("frames_failed", -1), 0) << s.dump();
  const long rss = peak_rss_kb(service.process->pid());
  RecordProperty("service_peak_rss_kb", std::to_string(rss));
  std::cout << "service peak RSS under " << kClients << " clients: " << rss / 1024 << " MiB\n";
  // The spool holds nothing once the replies are sent.
  EXPECT_TRUE(fs::is_empty(dir.path / "out" / ".ssdo-spool"));
  EXPECT_EQ(service.process->signal_and_wait(SIGTERM, 30), 0);
  EXPECT_FALSE(path_exists(service.socket));
}

// A client still sending when the service answers and ends its connection (the rest of a
// header over --max-request-bytes; an inline frame refused for its options before its bytes
// were read) finishes sending and reads the answer, instead of failing to send to a closed
// connection. Both messages are far larger than a socket's buffer.
TEST(ServeSocket, AClientStillSendingWhenAnsweredReadsTheAnswer) {
  ScratchDir dir;
  SocketService service(dir, "linger", {"--max-request-bytes", "4096", "--max-inline-mb", "16"});
  ASSERT_TRUE(service.ready) << service.log();
  {
    Client c(service.socket);
    std::string message(4 + (4 << 20), ' ');
    encode_length(uint32_t(message.size() - 4), reinterpret_cast<unsigned char*>(message.data()));
    EXPECT_EQ(write_all(c.fd(), message.data(), message.size(), deadline_in(10)), IoStatus::ok);
    EXPECT_EQ(c.read_response(nullptr, 10).value("code", ""), "too_large");
  }
  {
    Client c(service.socket);
    const json reply = c.request({{"op", "process"}, {"name", "late"}, {"options", {{"method", "magic"}}}},
                                 std::string(8 << 20, '\0'), nullptr, 10);
    EXPECT_EQ(reply.value("code", ""), "bad_request") << reply.dump();
  }
  EXPECT_EQ(ping(service.socket).value("ok", false), true);
}

TEST(ServeSocket, MalformedOversizeAndEscapingRequestsAreRefusedServiceStaysHealthy) {
  ScratchDir dir;
  SocketService service(dir, "refuse", {"--max-request-bytes", "4096", "--max-inline-mb", "1", "--client-timeout", "1.5"});
  ASSERT_TRUE(service.ready) << service.log();
  const std::string& socket = service.socket;

  {  // Not JSON.
    Client c(socket);
    ASSERT_EQ(write_message(c.fd(), "hello", deadline_in(5)), IoStatus::ok);
    EXPECT_EQ(c.read_response().value("code", ""), "bad_request");
  }
  {  // JSON, but not a valid request.
    Client c(socket);
    EXPECT_EQ(c.request({{"op", "process"}}).value("code", ""), "bad_request");
  }
  {  // A header cut short by the client's end of sending: told so, since it may still read.
    Client c(socket);
    unsigned char prefix[4];
    encode_length(100, prefix);
    ASSERT_EQ(write_all(c.fd(), prefix, 4, deadline_in(5)), IoStatus::ok);
    ASSERT_EQ(write_all(c.fd(), "{\"op\": \"pi", 10, deadline_in(5)), IoStatus::ok);
    ::shutdown(c.fd(), SHUT_WR);
    const json r = c.read_response(nullptr, 10);
    EXPECT_EQ(r.value("code", ""), "bad_request") << r.dump();
    EXPECT_NE(r.value("error", "").find("the request header was cut short"), std::string::npos) << r.dump();
  }
  {  // A header larger than --max-request-bytes: refused from its length alone.
    Client c(socket);
    unsigned char prefix[4];
    encode_length(100000, prefix);
    ASSERT_EQ(write_all(c.fd(), prefix, 4, deadline_in(5)), IoStatus::ok);
    EXPECT_EQ(c.read_response().value("code", ""), "too_large");
  }
  {  // An inline frame larger than --max-inline-mb.
    Client c(socket);
    const json reply = c.request({{"op", "process"}, {"inline_size", 2 << 20}});
    EXPECT_EQ(reply.value("code", ""), "bad_request") << reply.dump();
    EXPECT_NE(reply.value("error", "").find("limit"), std::string::npos) << reply.dump();
  }
  // Paths escaping --allow: "..", a symlink pointing out, an output outside --out.
  fs::create_directories(dir.path / "secret");
  copy_example("cornell", dir.path / "secret", "secret");
  fs::create_symlink(dir.path / "secret" / "secret.exr", dir.path / "frames" / "link.exr");
  for (const std::string& input : {dir / "frames/../secret/secret.exr", dir / "frames/link.exr", std::string("/etc/passwd")}) {
    const json reply = process_path(socket, input);
    EXPECT_EQ(reply.value("code", ""), "forbidden") << input << ": " << reply.dump();
  }
  for (const std::string& output : {dir / "frames/x.ssdo.exr", dir / "out/../x.ssdo.exr"}) {
    const json reply = process_path(socket, dir / "frames/cornell.exr", {{"output", output}});
    EXPECT_EQ(reply.value("code", ""), "forbidden") << output << ": " << reply.dump();
  }
  {  // Option paths are checked too.
    const json reply = process_path(socket, dir / "frames/cornell.exr", {{"options", {{"camera", "/etc/hostname"}}}});
    EXPECT_EQ(reply.value("code", ""), "forbidden") << reply.dump();
    const json bad = process_path(socket, dir / "frames/cornell.exr", {{"options", {{"method", "magic"}}}});
    EXPECT_EQ(bad.value("code", ""), "bad_request") << bad.dump();
  }
  EXPECT_FALSE(path_exists(dir.path / "x.ssdo.exr"));
  EXPECT_FALSE(path_exists(dir.path / "frames" / "x.ssdo.exr"));

  {  // A silent client does not block others, and is timed out.
    Client silent(socket);
    ASSERT_TRUE(silent.connected());
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_EQ(ping(socket).value("ok", false), true);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
    const json timeout = silent.read_response(nullptr, 10);
    EXPECT_EQ(timeout.value("code", ""), "timeout");
    EXPECT_EQ(timeout.value("error", ""), "no complete request within 1.5 s (--client-timeout)");
  }
  // Still healthy: a good frame is processed.
  const json good = process_path(socket, dir / "frames/cornell.exr");
  EXPECT_EQ(good.value("ok", false), true) << good.dump();
  EXPECT_TRUE(exr_has_channel(good.value("output", ""), "ao"));
  EXPECT_EQ(service.process->signal_and_wait(SIGTERM, 30), 0);
}

// Options no frame can be computed with are the request's error (bad_request, answered
// before any work): a frame failure's error file would replace the frame's good output.
// An "output" may not name the service's own files (lock, spool, temp files), error files
// or sidecars; a spool folder removed by hand is made again.
TEST(ServeSocket, BadOptionsAndForeignOutputNamesTouchNoOutput) {
  ScratchDir dir;
  SocketService service(dir, "badopts");
  ASSERT_TRUE(service.ready) << service.log();
  const std::string input = dir / "frames/cornell.exr";
  ASSERT_EQ(process_path(service.socket, input).value("ok", false), true);
  const fs::path output = dir.path / "out" / "cornell.ssdo.exr";
  ASSERT_TRUE(fs::exists(output));
  const auto written = fs::last_write_time(output);
  for (const json& options : {json{{"terms", ""}}, json{{"sky", "x"}}, json{{"composite", "bogus"}},
                              json{{"sky", "1,1"}, {"env-constant", 2}}, json{{"radius", 1e308}},
                              json{{"thickness", 1e300}}, json{{"camera", dir / "frames"}}}) {
    const json r = process_path(service.socket, input, {{"options", options}});
    EXPECT_EQ(r.value("code", ""), "bad_request") << options.dump() << " " << r.dump();
    EXPECT_FALSE(r.contains("error_file")) << r.dump();
  }
  EXPECT_TRUE(fs::exists(output));
  EXPECT_EQ(fs::last_write_time(output), written);
  EXPECT_FALSE(fs::exists(dir.path / "out" / "cornell.error.json"));

  for (const char* name : {".ssdo-serve.lock", "cornell.error.json", "cornell.camera.json", "noext", ".hidden.exr"}) {
    const json r = process_path(service.socket, input, {{"output", (dir.path / "out" / name).string()}});
    EXPECT_EQ(r.value("code", ""), "bad_request") << name << " " << r.dump();
  }
  EXPECT_LT(fs::file_size(dir.path / "out" / ".ssdo-serve.lock"), 64u);  // its pid, not an EXR

  fs::remove_all(dir.path / "out" / ".ssdo-spool");
  Client c(service.socket);
  const std::string bytes = read_text(input);
  std::string reply_bytes;
  const json sidecar = json::parse(read_text(dir.path / "frames" / "cornell.camera.json"));
  const json r =
      c.request({{"op", "process"}, {"name", "up"}, {"sidecar", sidecar}, {"reply", "inline"}}, bytes, &reply_bytes);
  EXPECT_EQ(r.value("ok", false), true) << r.dump();
  EXPECT_FALSE(reply_bytes.empty());
}

// Sends a frame of `input` on `client` to a service whose workers are held (HeldWorkers):
// true once it is in flight.
bool frame_in_flight(const Client& client, const SocketService& service, const std::string& input) {
  const json request = {{"op", "process"}, {"input", input}};
  return write_message(client.fd(), request.dump(), deadline_in(5)) == IoStatus::ok &&
         wait_until([&] { return stats(service.socket).value("in_flight", 0) == 1; }, 30);
}

// Sends a frame of `input` to `output` on `client` behind the one in flight: true once it
// waits in the queue.
bool frame_queued(const Client& client, const SocketService& service, const std::string& input,
                  const std::string& output) {
  const json request = {{"op", "process"}, {"input", input}, {"output", output}};
  return write_message(client.fd(), request.dump(), deadline_in(5)) == IoStatus::ok &&
         wait_until([&] { return stats(service.socket).value("queue_depth", 0) == 1; }, 30);
}

// A client that closes its connection while its frame waits gives its slot back at once
// (while the frame before it still computes), and its queued frame is dropped: nothing is
// computed or written for it.
TEST(ServeSocket, AClientThatLeavesGivesBackItsSlotAndItsQueuedFrame) {
  ScratchDir dir;
  SocketService service(dir, "leave", {"--jobs", "1"});
  ASSERT_TRUE(service.ready) << service.log();
  HeldWorkers held(service.process->pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  const std::string input = dir / "frames/cornell.exr";
  Client first(service.socket);
  ASSERT_TRUE(frame_in_flight(first, service, input)) << service.log();
  {
    Client gone(service.socket);
    ASSERT_TRUE(frame_queued(gone, service, input, (dir.path / "out" / "gone.exr").string())) << service.log();
    // first, gone and this request's own (once earlier stats requests' connections closed)
    EXPECT_TRUE(wait_until([&] { return stats(service.socket).value("clients", 0) == 3; }, 10));
  }
  // Its slot back: first's and the stats request's own only.
  EXPECT_TRUE(wait_until([&] { return stats(service.socket).value("clients", 0) == 2; }, 30));
  pollfd p{first.fd(), POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 0), 0) << "the first frame is still computing";
  held.release();
  EXPECT_EQ(first.read_response().value("ok", false), true);
  ASSERT_TRUE(wait_until([&] { return service.log().find("dropped") != std::string::npos; }, 30)) << service.log();
  EXPECT_NE(service.log().find("its client closed the connection while it was queued"), std::string::npos);
  EXPECT_EQ(stats(service.socket).value("queue_depth", -1), 0);
  EXPECT_FALSE(fs::exists(dir.path / "out" / "gone.exr"));
}

// A request whose client has gone is waited for by nobody: it leaves the queue when its client
// does, so it is no longer counted in queue_depth and its place goes to the next client, while
// the frame ahead of it is still computing.
TEST(ServeSocket, AQueuedRequestLeavesTheQueueWithItsClient) {
  ScratchDir dir;
  SocketService service(dir, "leaveq", {"--jobs", "1", "--queue", "1"});
  ASSERT_TRUE(service.ready) << service.log();
  HeldWorkers held(service.process->pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  const std::string input = dir / "frames/cornell.exr";
  Client first(service.socket);
  ASSERT_TRUE(frame_in_flight(first, service, input)) << service.log();
  {
    Client gone(service.socket);
    ASSERT_TRUE(frame_queued(gone, service, input, "gone.ssdo.exr")) << service.log();
  }
  // Its slot back (first's and the stats request's own only), while the first frame computes.
  ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("clients", 0) == 2; }, 10));
  const json after = stats(service.socket);
  EXPECT_EQ(after.value("queue_depth", -1), 0) << after.dump();
  EXPECT_EQ(after.value("in_flight", -1), 1) << after.dump();
  // The one place of the queue is free again: the next request waits in it, not "busy".
  Client next(service.socket);
  ASSERT_EQ(write_message(next.fd(), json{{"op", "process"}, {"input", input}, {"output", "next.ssdo.exr"}}.dump(),
                          deadline_in(5)),
            IoStatus::ok);
  EXPECT_TRUE(wait_until([&] { return stats(service.socket).value("queue_depth", 0) == 1; }, 10));
  held.release();
  EXPECT_EQ(first.read_response().value("ok", false), true);
  const json reply = next.read_response();
  EXPECT_EQ(reply.value("ok", false), true) << reply.dump();
  EXPECT_TRUE(fs::exists(dir.path / "out" / "next.ssdo.exr"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "gone.ssdo.exr"));
  EXPECT_EQ(count_occurrences(service.log(), "its client closed the connection while it was queued"), 1)
      << service.log();
}

// A client that never reads its inline reply holds the stop for a few seconds, not for its
// whole --client-timeout; the reply it did not take is cut short, never passed off as whole.
TEST(ServeSocket, AClientThatNeverReadsItsReplyDoesNotHoldTheStop) {
  ScratchDir dir;
  SocketService service(dir, "unread", {"--jobs", "1", "--client-timeout", "600"});
  ASSERT_TRUE(service.ready) << service.log();
  Client unread(service.socket);
  // Every term of a 640x360 frame, uncompressed: megabytes, more than the socket's
  // buffers hold, so the reply waits for a client that does not come.
  const json request = {{"op", "process"},
                        {"input", dir / "frames/cornell.exr"},
                        {"reply", "inline"},
                        {"options", {{"terms", "all"}, {"compression", "none"}}}};
  ASSERT_EQ(write_message(unread.fd(), request.dump(), deadline_in(5)), IoStatus::ok);
  ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("frames_done", 0) == 1; }, 60)) << service.log();
  const auto signalled = Clock::now();
  EXPECT_EQ(service.process->signal_and_wait(SIGTERM, 120), 0) << service.log();
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - signalled).count(), 60.0) << "held back by the client";
  EXPECT_EQ(unread.read_response(nullptr, 10).value("transport_error", ""), "inline");
  EXPECT_FALSE(path_exists(service.socket));
}

// An inline frame dropped from the queue because its client left is logged under its name,
// not under the spool path the client never saw.
TEST(ServeSocket, AnInlineFrameDroppedFromTheQueueIsLoggedUnderItsName) {
  ScratchDir dir;
  SocketService service(dir, "inlinedrop", {"--jobs", "1"});
  ASSERT_TRUE(service.ready) << service.log();
  HeldWorkers held(service.process->pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  Client first(service.socket);
  ASSERT_TRUE(frame_in_flight(first, service, dir / "frames/cornell.exr")) << service.log();
  {
    Client gone(service.socket);
    const std::string bytes = read_text(dir.path / "frames" / "cornell.exr");
    const json header = {{"op", "process"}, {"name", "shot9"}, {"inline_size", bytes.size()}};
    ASSERT_EQ(write_message(gone.fd(), header.dump(), deadline_in(5)), IoStatus::ok);
    ASSERT_EQ(write_all(gone.fd(), bytes.data(), bytes.size(), deadline_in(30)), IoStatus::ok);
    ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("queue_depth", 0) == 1; }, 30)) << service.log();
  }
  ASSERT_TRUE(wait_until([&] { return service.log().find("dropped") != std::string::npos; }, 30)) << service.log();
  EXPECT_NE(service.log().find("dropped inline frame shot9: its client closed the connection"), std::string::npos)
      << service.log();
  EXPECT_EQ(service.log().find(".ssdo-spool"), std::string::npos) << service.log();
  held.release();
  EXPECT_EQ(first.read_response().value("ok", false), true);
}

// An inline frame's errors name it as the client knows it, not by the service's private
// spool path (gone once the client is answered); its error file too.
TEST(ServeSocket, AnInlineFramesErrorsNameTheFrameNotTheSpool) {
  ScratchDir dir;
  SocketService service(dir, "inlineerr");
  ASSERT_TRUE(service.ready) << service.log();
  Client client(service.socket);
  const json r = client.request({{"op", "process"}, {"name", "shot7"}}, read_text(dir.path / "frames" / "cornell.exr"));
  EXPECT_EQ(r.value("code", ""), "frame_failed") << r.dump();
  const std::string error = r.value("error", "");
  EXPECT_EQ(error.find(".ssdo-spool"), std::string::npos) << error;
  EXPECT_EQ(error.rfind("inline frame shot7: no camera: give a JSON sidecar (the request's \"sidecar\"", 0), 0u) << error;
  const json file = json::parse(read_text(dir.path / "out" / "shot7.error.json"), nullptr, false);
  EXPECT_EQ(file.value("error", ""), error);
  EXPECT_EQ(file.value("input", ""), "inline frame shot7");
  EXPECT_TRUE(wait_until([&] { return service.log().find("FAILED inline frame shot7: ") != std::string::npos; }, 10))
      << service.log();
  EXPECT_EQ(service.log().find(".ssdo-spool"), std::string::npos) << service.log();
}

// An explicit "output" never replaces a frame (the input, a file that is not ssdo's): a
// success would overwrite it and a failure remove it. One the service wrote is replaced.
// A failed frame leaves none of its earlier previews either.
TEST(ServeSocket, AnOutputNeverReplacesAFrameOrAnotherProgramsFile) {
  ScratchDir dir;
  fs::create_directories(dir.path / "out");
  SocketService service(dir, "noreplace", {"--allow", dir / "out"});
  ASSERT_TRUE(service.ready) << service.log();
  fs::copy_file(dir.path / "frames" / "cornell.exr", dir.path / "out" / "frame.exr");
  fs::copy_file(dir.path / "frames" / "cornell.camera.json", dir.path / "out" / "frame.camera.json");
  fs::copy_file(dir.path / "frames" / "greeble.exr", dir.path / "out" / "theirs.exr");
  const std::string frame_bytes = read_text(dir.path / "out" / "frame.exr");
  json r = process_path(service.socket, dir / "out/frame.exr", {{"output", dir / "out/frame.exr"}});
  EXPECT_EQ(r.value("code", ""), "bad_request") << r.dump();
  EXPECT_NE(r.value("error", "").find("is the input frame"), std::string::npos) << r.dump();
  r = process_path(service.socket, dir / "frames/cornell.exr", {{"output", dir / "out/theirs.exr"}});
  EXPECT_EQ(r.value("code", ""), "conflict") << r.dump();
  EXPECT_NE(r.value("error", "").find("is not an output of ssdo"), std::string::npos) << r.dump();
  EXPECT_EQ(read_text(dir.path / "out" / "frame.exr"), frame_bytes);
  EXPECT_EQ(read_text(dir.path / "out" / "theirs.exr"), read_text(dir.path / "frames" / "greeble.exr"));
  for (int run = 0; run < 2; ++run) {  // written, then replaced: the service's own output
    r = process_path(service.socket, dir / "frames/cornell.exr", {{"output", dir / "out/mine.exr"}});
    EXPECT_EQ(r.value("ok", false), true) << r.dump();
  }
  // A relative output is under --out, whatever the service's working folder.
  r = process_path(service.socket, dir / "frames/cornell.exr", {{"output", "relative.exr"}});
  EXPECT_EQ(r.value("output", ""), dir / "out/relative.exr") << r.dump();
  // Previews of a frame that then fails are removed with its output.
  r = process_path(service.socket, dir / "frames/greeble.exr", {{"options", {{"png", true}}}});
  ASSERT_EQ(r.value("ok", false), true) << r.dump();
  ASSERT_TRUE(fs::exists(dir.path / "out" / "greeble.ssdo.ao.png"));
  std::ofstream(dir.path / "out" / "greeble.ssdo.notes.txt.png") << "not a preview";
  r = process_path(service.socket, dir / "frames/greeble.exr", {{"options", {{"part", "nope"}}}});
  EXPECT_EQ(r.value("code", ""), "frame_failed") << r.dump();
  EXPECT_FALSE(fs::exists(dir.path / "out" / "greeble.ssdo.exr"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "greeble.ssdo.ao.png"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "greeble.ssdo.confidence.png"));
  EXPECT_TRUE(fs::exists(dir.path / "out" / "greeble.ssdo.notes.txt.png"));
  // An explicit output's error file is named after it: never a watched frame's (b.exr's is
  // b.error.json) nor "x.ssdo.error.json".
  for (const char* name : {"b.exr", "x.ssdo.exr"}) {
    r = process_path(service.socket, dir / "frames/greeble.exr", {{"output", dir / ("out/" + std::string(name))}, {"options", {{"part", "nope"}}}});
    EXPECT_EQ(r.value("code", ""), "frame_failed") << r.dump();
  }
  EXPECT_TRUE(fs::exists(dir.path / "out" / "b.exr.error.json"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "b.error.json"));
  EXPECT_TRUE(fs::exists(dir.path / "out" / "x.error.json"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "x.ssdo.error.json"));
}

// Two uploads of one name at once: the second is told of the conflict instead of both
// being told "ok" while one replaces the other's result.
TEST(ServeSocket, TwoUploadsOfOneNameAtOnceConflict) {
  ScratchDir dir;
  SocketService service(dir, "samename", {"--jobs", "2"});
  ASSERT_TRUE(service.ready) << service.log();
  HeldWorkers held(service.process->pid(), 2);
  ASSERT_TRUE(held.held()) << service.log();
  const std::string bytes = read_text(dir.path / "frames" / "cornell.exr");
  const json sidecar = json::parse(read_text(dir.path / "frames" / "cornell.camera.json"));
  Client first(service.socket);
  json upload{{"op", "process"}, {"name", "same"}, {"sidecar", sidecar}, {"inline_size", bytes.size()}};
  ASSERT_EQ(write_message(first.fd(), upload.dump(), deadline_in(5)), IoStatus::ok);
  ASSERT_EQ(write_all(first.fd(), bytes.data(), bytes.size(), deadline_in(5)), IoStatus::ok);
  ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("in_flight", 0) == 1; }, 30)) << service.log();
  Client second(service.socket);
  const json r = second.request({{"op", "process"}, {"name", "same"}, {"sidecar", sidecar}}, bytes);
  EXPECT_EQ(r.value("code", ""), "conflict") << r.dump();
  EXPECT_NE(r.value("error", "").find("is being computed for another request now"), std::string::npos) << r.dump();
  held.release();
  EXPECT_EQ(first.read_response().value("ok", false), true);
  // Once it is done, the name is free again.
  Client third(service.socket);
  const json again = third.request({{"op", "process"}, {"name", "same"}, {"sidecar", sidecar}}, bytes);
  EXPECT_EQ(again.value("ok", false), true) << again.dump();
}

TEST(ServeSocket, FullQueueAnswersBusy) {
  ScratchDir dir;
  SocketService service(dir, "busy", {"--jobs", "1", "--queue", "1"});
  ASSERT_TRUE(service.ready) << service.log();
  constexpr int kClients = 6;
  std::vector<json> replies(kClients);
  std::vector<std::thread> threads;
  for (int i = 0; i < kClients; ++i)
    threads.emplace_back([&, i] {
      replies[i] = process_path(service.socket, dir / "frames/greeble.exr",
                                {{"output", dir / ("out/b" + std::to_string(i) + ".ssdo.exr")},
                                 {"options", {{"preset", "high"}}}});
    });
  for (auto& t : threads) t.join();
  int ok = 0, busy = 0;
  for (const json& r : replies) {
    ok += r.value("ok", false);
    busy += r.value("code", "") == "busy";
  }
  EXPECT_GE(ok, 1);
  EXPECT_GE(busy, 1);
  EXPECT_EQ(ok + busy, kClients);
  EXPECT_EQ(ping(service.socket).value("ok", false), true);
}

TEST(ServeSocket, PoisonFramesOverTheSocketEachGetAnError) {
  SSDO_REQUIRE_CONFORMANCE();
  ScratchDir dir;
  const std::string damaged = (shared_dir() / "exr-conformance" / "damaged").string();
  SocketService service(dir, "poison", {"--allow", damaged, "--memory-limit", "1024"});
  ASSERT_TRUE(service.ready) << service.log();
  const auto files = damaged_files();
  std::atomic<size_t> next{0};
  std::atomic<int> errors{0};
  std::mutex mutex;
  std::vector<std::string> unexpected;
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      Client c(service.socket);
      for (size_t i; (i = next.fetch_add(1)) < files.size();) {
        // Half by path, half inline.
        json reply;
        if (i % 2) {
          reply = c.request({{"op", "process"}, {"input", files[i].string()}});
        } else {
          std::string bytes = read_text(files[i]);
          if (bytes.empty()) bytes = " ";
          reply = c.request({{"op", "process"}, {"name", "poison" + std::to_string(i)}}, bytes);
        }
        if (reply.value("code", "") == "frame_failed") {
          ++errors;
        } else {
          std::lock_guard<std::mutex> lock(mutex);
          unexpected.push_back(files[i].filename().string() + ": " + reply.dump());
        }
      }
      (void)t;
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(errors.load(), int(files.size()));
  EXPECT_TRUE(unexpected.empty()) << unexpected.front();
  EXPECT_EQ(ping(service.socket).value("ok", false), true);
  const json good = process_path(service.socket, dir / "frames/cornell.exr");
  EXPECT_EQ(good.value("ok", false), true) << good.dump();
  EXPECT_EQ(service.process->signal_and_wait(SIGTERM, 30), 0);
}

// A second signal stops at once, the frame in flight abandoned (its client told so by the
// connection's end).
TEST(ServeSocket, ASecondSignalStopsAtOnce) {
  ScratchDir dir;
  SocketService service(dir, "twice", {"--jobs", "1"});
  ASSERT_TRUE(service.ready) << service.log();
  HeldWorkers held(service.process->pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  json reply;
  std::thread slow([&] { reply = process_path(service.socket, dir / "frames/cornell.exr"); });
  ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("in_flight", 0) == 1; }, 20));
  ::kill(service.process->pid(), SIGTERM);
  ASSERT_TRUE(service.process->wait_for_log("a second signal stops at once", 30)) << service.log();
  EXPECT_EQ(service.process->signal_and_wait(SIGTERM, 30), 128 + SIGTERM) << service.log();
  slow.join();
  EXPECT_TRUE(reply.contains("transport_error")) << reply.dump();
}

// SIGTERM, and SIGHUP (the terminal or ssh session that started it closed) alike.
TEST(ServeSocket, GracefulStopFinishesTheFrameInFlight) {
  for (const int sig : {SIGTERM, SIGHUP}) {
    ScratchDir dir;
    SocketService service(dir, "graceful", {"--jobs", "1"});
    ASSERT_TRUE(service.ready) << service.log();
    json reply;
    std::thread slow([&] {
      reply = process_path(service.socket, dir / "frames/cornell.exr", {{"options", {{"preset", "ultra"}}}});
    });
    ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("in_flight", 0) == 1; }, 20));
    EXPECT_EQ(service.process->signal_and_wait(sig, 60), 0) << service.log();
    slow.join();
    EXPECT_EQ(reply.value("ok", false), true) << reply.dump();
    EXPECT_TRUE(exr_has_channel(reply.value("output", ""), "ao"));
    EXPECT_FALSE(path_exists(service.socket));
    EXPECT_NE(service.log().find(sig == SIGHUP ? "SIGHUP: stopping" : "SIGTERM: stopping"), std::string::npos)
        << service.log();
  }
}

// A frame replaced while a request computes it: the reply says its result may be of the old
// version, and the output is dated back behind the new one (a watch or a batch over the
// folder then computes it again), as `ssdo process` and the watch do.
TEST(ServeSocket, AFrameReplacedWhileComputedIsSaidAndItsOutputLeftOutOfDate) {
  ScratchDir dir;
  SocketService service(dir, "replaced", {"--jobs", "1"});
  ASSERT_TRUE(service.ready) << service.log();
  HeldWorkers held(service.process->pid(), 1);
  ASSERT_TRUE(held.held()) << service.log();
  const fs::path input = dir.path / "frames" / "cornell.exr";
  json reply;
  std::thread request([&] { reply = process_path(service.socket, input.string()); });
  // In flight: the service took the frame as it was then, whichever version its held worker
  // then reads.
  ASSERT_TRUE(wait_until([&] { return stats(service.socket).value("in_flight", 0) == 1; }, 20));
  fs::copy_file(example_frame("greeble.exr"), dir.path / "frames" / ".cornell.exr.part");
  fs::rename(dir.path / "frames" / ".cornell.exr.part", input);
  held.release();
  request.join();
  ASSERT_EQ(reply.value("ok", false), true) << reply.dump();
  const json warnings = reply.value("warnings", json::array());
  ASSERT_EQ(warnings.size(), 1u) << reply.dump();
  EXPECT_NE(warnings[0].get<std::string>().find("changed while it was computed"), std::string::npos) << reply.dump();
  EXPECT_LT(fs::last_write_time(reply.value("output", "")), fs::last_write_time(input));
  // A frame left alone gets no warning.
  const json calm = process_path(service.socket, (dir.path / "frames" / "greeble.exr").string());
  EXPECT_EQ(calm.value("ok", false), true) << calm.dump();
  EXPECT_FALSE(calm.contains("warnings")) << calm.dump();
}

TEST(ServeSocket, ClientCommandSpeaksTheProtocol) {
  ScratchDir dir;
  SocketService service(dir, "client");
  ASSERT_TRUE(service.ready) << service.log();
  const std::string s = " --socket " + service.socket + " ";
  RunResult r = run_ssdo("client" + s + "ping");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"ok\":true"), std::string::npos) << r.output;
  r = run_ssdo("client" + s + "stats");
  EXPECT_NE(r.output.find("queue_depth"), std::string::npos) << r.output;
  r = run_ssdo("client" + s + "process " + dir / "frames/cornell.exr" + " " + dir / "frames/greeble.exr");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "out/cornell.ssdo.exr", "ao"));
  EXPECT_TRUE(exr_has_channel(dir / "out/greeble.ssdo.exr", "ao"));
  r = run_ssdo("client" + s + "process --inline -o " + dir / "inline" + " " + example_frame("cornell.exr") +
               " --terms ao,ssdo");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "inline/cornell.ssdo.exr", "ssdo_direct.R")) << r.output;
  // A frame outside --allow: an error, exit 1.
  r = run_ssdo("client" + s + "process " + example_frame("cornell.exr"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("forbidden"), std::string::npos) << r.output;
  EXPECT_EQ(run_ssdo("client --socket /nonexistent.sock ping").exit_code, 2);
  // Frame options belong to process requests: refused with stats, not silently dropped.
  r = run_ssdo("client" + s + "stats --method hbao");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("stats takes no frame options (method given)"), std::string::npos) << r.output;
  // A refused file does not end the list: each file gets its line, the later ones computed.
  r = run_ssdo("client" + s + "process " + dir / "frames" + " " + dir / "frames/greeble.exr" + " -o " + dir / "o2");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("not a regular file"), std::string::npos) << r.output;
  EXPECT_EQ(count_occurrences(r.output, "\"ok\":true"), 1) << r.output;
  // Inline frames whose names are no plain stems (a space, non-ASCII) are sent under one.
  fs::copy_file(example_frame("cornell.exr"), dir.path / "frames" / "shot A \xc3\xbc.exr");
  fs::copy_file(example_frame("cornell.camera.json"), dir.path / "frames" / "shot A \xc3\xbc.camera.json");
  r = run_ssdo("client" + s + "process --inline -o " + dir / "inline" + " '" + dir / "frames/shot A \xc3\xbc.exr" + "' " +
               example_frame("greeble.exr"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "inline/shot A \xc3\xbc.ssdo.exr", "ao")) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "inline/greeble.ssdo.exr", "ao")) << r.output;
  // An inline file that cannot be read (a folder, a missing file) gets its own line and the
  // next files are still sent; so are the files after a forbidden request (which closes
  // the connection). No abort.
  fs::remove(dir.path / "inline" / "greeble.ssdo.exr");
  r = run_ssdo("client" + s + "process --inline -o " + dir / "inline" + " " + dir / "frames" + " " + dir / "none.exr" +
               " " + example_frame("greeble.exr"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("a folder, not a file"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("no such file"), std::string::npos) << r.output;
  EXPECT_EQ(count_occurrences(r.output, "\"ok\":true"), 1) << r.output;
  EXPECT_TRUE(exr_has_channel(dir / "inline/greeble.ssdo.exr", "ao")) << r.output;
  // With --inline the service reads no file of the client's: a --camera file is read by
  // the client and sent as the sidecar; one that is no camera JSON is refused before any
  // request.
  r = run_ssdo("client" + s + "process --inline -o " + dir / "inline" + " " + example_frame("cornell.exr") + " " +
               example_frame("greeble.exr") + " --camera /etc/passwd");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/etc/passwd: --camera: not a JSON object"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("\"ok\""), std::string::npos) << r.output;
  // Two files of one name would write one output: refused before any is sent; an output
  // folder that is a file: refused.
  r = run_ssdo("client" + s + "process --inline -o " + dir / "inline" + " " + example_frame("cornell.exr") + " " +
               dir / "frames/cornell.exr");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("would both be written to " + dir / "inline/cornell.ssdo.exr"), std::string::npos)
      << r.output;
  std::ofstream(dir.path / "afile") << "x";
  r = run_ssdo("client" + s + "process --inline -o " + dir / "afile" + " " + example_frame("cornell.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("cannot create the folder"), std::string::npos) << r.output;
}

// The files a client's options name (--camera, --env) are the ones its own working
// directory gives, not the service's: sent as absolute paths (by path), or the camera as
// the request's sidecar (--inline). A relative --camera was read from the service's folder.
TEST(ServeSocket, ClientOptionsNameFilesFromTheClientsFolder) {
  ScratchDir dir;
  SocketService service(dir, "client-paths");
  ASSERT_TRUE(service.ready) << service.log();
  fs::create_directories(dir.path / "frames/sub");
  fs::copy_file(example_frame("cornell.exr"), dir.path / "frames/sub/f.exr");
  fs::copy_file(example_frame("cornell.camera.json"), dir.path / "frames/sub/cam.json");
  const fs::path before = fs::current_path();
  fs::current_path(dir.path / "frames/sub");
  const RunResult by_path = run_ssdo("client --socket " + service.socket + " process f.exr --camera cam.json");
  const RunResult inline_camera = run_ssdo("client --socket " + service.socket + " process --inline -o " +
                                           dir / "inline" + " f.exr --camera cam.json");
  fs::current_path(before);
  ASSERT_EQ(by_path.exit_code, 0) << by_path.output;
  auto in = OIIO::ImageInput::open((dir.path / "out/f.ssdo.exr").string());
  ASSERT_TRUE(in);
  const json options = json::parse(in->spec().get_string_attribute("ssdo/options"), nullptr, false);
  in.reset();
  EXPECT_EQ(options.value("camera", ""), (dir.path / "frames/sub/cam.json").string());
  // The inline frame has no NAME.camera.json beside it: its camera came from --camera.
  EXPECT_EQ(inline_camera.exit_code, 0) << inline_camera.output;
  EXPECT_TRUE(exr_has_channel(dir / "inline/f.ssdo.exr", "ao")) << inline_camera.output;
}

}  // namespace
}  // namespace ssdo::test
