// Integration-test helpers for the long-running parts: a real `ssdo serve` (or batch)
// process started with an argument vector and its output in a log file, a socket client
// speaking the service protocol, and deadline-bounded waiting. Every process a test
// starts is killed in the destructor of its handle.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/sanitizer_build.h"
#include "run_binary.h"
#include "service/protocol.h"

extern char** environ;

namespace ssdo::test {

namespace fs = std::filesystem;
using json = nlohmann::json;

// The --frame-timeout of the services the tests start: a stalled frame fails its test in a
// minute, and the slowest frame a test puts in flight has room (the ultra preset on the
// 640 x 360 example: 0.3 s here, 1.6 s in the sanitizer build, 3 s there beside a build).
inline const std::string kServiceFrameTimeoutS = "60";

// The method and preset of frames that compute for a while, for the tests that need one
// frame's compute to span their own steps rather than only to be in flight (a frame in
// flight is a held worker's: HeldWorkers). The sanitizer build runs the kernels several
// times slower, the AO oracle most (7x: 10.5 s against 1.5 s on the 2-core AVX-512
// machine): there the same wait is bought with cheaper methods.
// kSecondFrame: about a second per 640 x 360 example frame, so that a file rewritten once a
// frame is in flight is rewritten while it is computed.
// kShotFrame: a seven-frame shot with --views 2 and one job writes its first output after
// about 0.8 s and its last 1.1 s later (GTAO high on the 2-core Intel machine; HBAO ultra
// took 8 s for the same), so that a kill polled every 20 ms lands mid-batch. The sanitizer
// build keeps HBAO high, chosen to match HBAO ultra's pace here (it computes HBAO 2-3x
// slower): slower than the kill needs, never too fast.
struct SlowFrame {
  const char* method;
  const char* preset;
};
#ifdef SSDO_SANITIZER_BUILD
inline constexpr SlowFrame kSecondFrame{"gtao", "ultra"};  // 1.6 s (the AO oracle at low: 10.5 s)
inline constexpr SlowFrame kShotFrame{"hbao", "high"};
#else
inline constexpr SlowFrame kSecondFrame{"raymarch", "low"};  // 1.5 s
inline constexpr SlowFrame kShotFrame{"gtao", "high"};
#endif

// Polls `condition` every 20 ms until it holds or `seconds` pass.
inline bool wait_until(const std::function<bool()>& condition, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!condition()) {
    if (std::chrono::steady_clock::now() >= end) return condition();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

inline int count_occurrences(const std::string& text, const std::string& needle) {
  int n = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + needle.size())) ++n;
  return n;
}

// PREFIX + N (appended, not operator+: GCC 12 warns falsely on "literal" + to_string).
inline std::string numbered(const char* prefix, int n) {
  std::string s(prefix);
  s.append(std::to_string(n));
  return s;
}

inline std::string example_frame(const std::string& name) {
  return (source_dir() / "examples" / "frames" / name).string();
}

// Copies an example frame and its camera sidecar as DIR/STEM.exr + DIR/STEM.camera.json
// (sidecar first: the frame is the file the service reacts to).
inline void copy_example(const std::string& example_stem, const fs::path& dir, const std::string& stem) {
  fs::copy_file(example_frame(example_stem + ".camera.json"), dir / (stem + ".camera.json"),
                fs::copy_options::overwrite_existing);
  fs::copy_file(example_frame(example_stem + ".exr"), dir / (stem + ".exr"), fs::copy_options::overwrite_existing);
}

// A readable EXR with the given channel.
inline bool exr_has_channel(const std::string& path, const std::string& channel) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return false;
  const auto& names = in->spec().channelnames;
  return std::find(names.begin(), names.end(), channel) != names.end();
}

// What an EXR holds, as one string: its windows, every header attribute (name, type, value),
// the channels' names and types, and every sample's bits (read as float: half widens
// exactly); empty when unreadable. Two outputs are the same frame when these are equal,
// whatever bytes their codec wrote: ISA-L's deflate (zip's default level) may pick other
// matches for the same samples on another CPU and, rarely, on another run.
inline std::string exr_content(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return {};
  const OIIO::ImageSpec spec = in->spec();
  std::ostringstream s;
  s << spec.x << ' ' << spec.y << ' ' << spec.width << ' ' << spec.height << ' ' << spec.full_x << ' '
    << spec.full_y << ' ' << spec.full_width << ' ' << spec.full_height << '\n';
  for (const OIIO::ParamValue& p : spec.extra_attribs)
    s << p.name() << ' ' << p.type().c_str() << ' ' << p.get_string(1 << 20) << '\n';
  for (int c = 0; c < spec.nchannels; ++c) s << spec.channelnames[size_t(c)] << ' ' << spec.channelformat(c).c_str() << '\n';
  std::vector<float> samples(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, samples.data())) return {};
  s.write(reinterpret_cast<const char*>(samples.data()), std::streamsize(samples.size() * sizeof(float)));
  return s.str();
}

// One channel of an EXR as floats, row-major; empty when unreadable or absent.
inline std::vector<float> exr_channel_pixels(const std::string& path, const std::string& channel) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return {};
  const auto& names = in->spec().channelnames;
  const int c = int(std::find(names.begin(), names.end(), channel) - names.begin());
  if (c == int(names.size())) return {};
  std::vector<float> pixels(size_t(in->spec().width) * size_t(in->spec().height));
  in->read_image(0, 0, c, c + 1, OIIO::TypeDesc::FLOAT, pixels.data());
  return pixels;
}

// Names in `dir` that look like temp files of a writer (".NAME.tmp-...").
inline std::vector<std::string> temp_files(const fs::path& dir) {
  std::vector<std::string> found;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.find(".tmp-") != std::string::npos) found.push_back(name);
  }
  return found;
}

// A file of /proc/PID, empty when the process is gone. A process can exit between the open
// and the read (other tests' processes come and go while workers_of scans /proc); the read
// then fails with ESRCH, which an ifstream reports by throwing from its buffer's underflow.
inline std::string read_proc_text(const std::string& path) {
  std::string text;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return text;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fd, buffer, sizeof buffer)) > 0;) text.append(buffer, size_t(n));
  ::close(fd);
  return text;
}

// A field of /proc/PID/status in KiB (VmRSS, VmSize), 0 when absent.
inline long status_kib(pid_t pid, const std::string& field) {
  const std::string status = read_proc_text("/proc/" + std::to_string(pid) + "/status");
  const size_t at = status.find(field + ":");
  return at == std::string::npos ? 0 : std::stol(status.substr(at + field.size() + 1));
}

// Processes whose command line says they are workers of `parent`.
inline std::vector<pid_t> workers_of(pid_t parent) {
  std::vector<pid_t> pids;
  const std::string marker = std::string("--parent") + '\0' + std::to_string(parent) + '\0';
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || !std::isdigit(static_cast<unsigned char>(name[0]))) continue;
    const std::string cmdline = read_proc_text(e.path() / "cmdline");
    if (cmdline.find("worker") != std::string::npos && cmdline.find(marker) != std::string::npos)
      pids.push_back(pid_t(std::stol(name)));
  }
  return pids;
}

// The state letter of /proc/PID/stat ('T': stopped), 0 when the process is gone.
inline char process_state(pid_t pid) {
  const std::string stat = read_proc_text("/proc/" + std::to_string(pid) + "/stat");
  const size_t name_end = stat.rfind(')');
  return name_end == std::string::npos || name_end + 2 >= stat.size() ? 0 : stat[name_end + 2];
}

// The workers of a batch or service held stopped (SIGSTOP) until release() or the end of
// this object's life (SIGCONT). A frame sent to a held worker stays in flight, computing
// nothing, for as long as a test needs to signal, replace a file or leave around it, and
// ends as soon as the worker is let go: what a slow frame would give without burning both
// cores for seconds, and without its race (a slow frame can still end before a loaded
// machine gets to the test's next step). The worker's parent only sees a frame that takes
// a while: its --frame-timeout counts the held time. Declare it after the process it holds
// the workers of, so that they are let go before that process is stopped.
class HeldWorkers {
 public:
  // Waits up to `seconds` for `count` workers of `parent` (a service starts its workers when
  // ready, a batch at its first frame), stops them, and waits until each is stopped.
  HeldWorkers(pid_t parent, size_t count, double seconds = 30) {
    if (!wait_until([&] { return (pids_ = workers_of(parent)).size() >= count; }, seconds)) return;
    for (const pid_t pid : pids_) ::kill(pid, SIGSTOP);
    held_ = wait_until(
        [&] {
          for (const pid_t pid : pids_)
            if (process_state(pid) != 'T') return false;
          return true;
        },
        10);
  }
  ~HeldWorkers() { release(); }
  HeldWorkers(const HeldWorkers&) = delete;
  HeldWorkers& operator=(const HeldWorkers&) = delete;

  bool held() const { return held_; }
  const std::vector<pid_t>& pids() const { return pids_; }
  void release() {
    for (const pid_t pid : pids_) ::kill(pid, SIGCONT);
    pids_.clear();
    held_ = false;
  }

 private:
  std::vector<pid_t> pids_;
  bool held_ = false;
};

// A running ssdo process (serve or process) with its output in a log file.
class SsdoProcess {
 public:
  SsdoProcess(const std::vector<std::string>& args, const fs::path& log) : log_(log) {
    std::vector<std::string> argv_strings = {SSDO_BINARY};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& s : argv_strings) argv.push_back(s.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (::posix_spawn(&pid_, SSDO_BINARY, &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  // A graceful stop first (the service removes its socket file), then SIGKILL.
  ~SsdoProcess() {
    if (running()) signal_and_wait(SIGTERM, 5);
    kill_now();
  }
  SsdoProcess(const SsdoProcess&) = delete;
  SsdoProcess& operator=(const SsdoProcess&) = delete;

  pid_t pid() const { return pid_; }
  std::string log() const { return read_text(log_); }
  bool wait_for_log(const std::string& text, double seconds) const {
    return wait_until([&] { return log().find(text) != std::string::npos || !running(); }, seconds) &&
           log().find(text) != std::string::npos;
  }
  bool running() const {
    if (pid_ <= 0 || exited_) return false;
    int status = 0;
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      exited_ = true;
      status_ = status;
      return false;
    }
    return true;
  }
  // Sends `sig` and waits up to `seconds` for the exit; returns the exit code (128 + signal
  // when killed), or -1 when it did not exit in time.
  int signal_and_wait(int sig, double seconds) {
    if (running()) ::kill(pid_, sig);
    if (!wait_until([&] { return !running(); }, seconds)) return -1;
    return WIFEXITED(status_) ? WEXITSTATUS(status_) : 128 + WTERMSIG(status_);
  }
  void kill_now() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status_, 0);
      exited_ = true;
    }
  }

 private:
  fs::path log_;
  pid_t pid_ = -1;
  mutable bool exited_ = false;
  mutable int status_ = 0;
};

// One connection to the service socket.
class Client {
 public:
  explicit Client(const std::string& socket_path) {
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, socket_path.c_str(), sizeof addr.sun_path - 1);
    fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~Client() {
    if (fd_ >= 0) ::close(fd_);
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  bool connected() const { return fd_ >= 0; }
  int fd() const { return fd_; }

  // Sends a request (+ payload bytes) and reads the response (+ its inline bytes).
  // A transport failure gives {"transport_error": "..."}.
  json request(json header, const std::string& payload = {}, std::string* inline_out = nullptr,
               double timeout_s = 120) {
    const Deadline deadline = deadline_in(timeout_s);
    if (!payload.empty()) header["inline_size"] = payload.size();
    if (write_message(fd_, header.dump(), deadline) != IoStatus::ok) return {{"transport_error", "send"}};
    if (!payload.empty() && write_all(fd_, payload.data(), payload.size(), deadline) != IoStatus::ok)
      return {{"transport_error", "send payload"}};
    return read_response(inline_out, timeout_s);
  }
  json read_response(std::string* inline_out = nullptr, double timeout_s = 120) {
    const Deadline deadline = deadline_in(timeout_s);
    std::string text;
    const IoStatus s = read_message(fd_, text, size_t(1) << 20, deadline);
    if (s != IoStatus::ok) return {{"transport_error", to_string(s)}};
    json j = json::parse(text, nullptr, false);
    if (j.is_discarded()) return {{"transport_error", "malformed response"}};
    const uint64_t n = j.value("inline_size", uint64_t(0));
    std::string bytes(n, '\0');
    if (n > 0 && read_exact(fd_, bytes.data(), n, deadline) != IoStatus::ok) return {{"transport_error", "inline"}};
    if (inline_out) *inline_out = std::move(bytes);
    return j;
  }

 private:
  int fd_ = -1;
};

inline json ping(const std::string& socket_path) {
  Client c(socket_path);
  if (!c.connected()) return {{"transport_error", "connect"}};
  return c.request({{"op", "ping"}}, {}, nullptr, 10);
}

inline json stats(const std::string& socket_path) {
  Client c(socket_path);
  if (!c.connected()) return {{"transport_error", "connect"}};
  return c.request({{"op", "stats"}}, {}, nullptr, 10);
}

// Short socket paths: sun_path holds 108 bytes, temp folders can be longer.
inline std::string socket_path_for(const std::string& tag) {
  return "/tmp/ssdo-it-" + std::to_string(::getpid()) + "-" + tag + ".sock";
}

inline bool path_exists(const fs::path& p) {
  std::error_code ec;
  return fs::exists(p, ec);
}

#define SSDO_REQUIRE_CONFORMANCE()                                                              \
  do {                                                                                          \
    if (!std::filesystem::exists(::ssdo::test::shared_dir() / "exr-conformance" / "damaged"))   \
      GTEST_SKIP() << "../shared/exr-conformance/damaged not found beside the clone: "          \
                   << ::ssdo::test::shared_dir();                                               \
  } while (0)

inline std::vector<fs::path> damaged_files() {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(shared_dir() / "exr-conformance" / "damaged"))
    if (e.is_regular_file() && e.path().filename() != "README.rst") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace ssdo::test
