#include "service/worker_process.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include "service/frame_list.h"
#include "service/protocol.h"

extern char** environ;

namespace ssdo {

namespace {

// Responses are small JSON objects; anything larger is a broken worker.
constexpr size_t kMaxResponseBytes = size_t(1) << 20;
// How long a reply may take once its first byte is there: it is written at once, after the
// frame (its time is the frame timeout's).
constexpr double kReplySeconds = 30.0;
// Time a worker gets to write its request's response once it is past its deadline
// (none) and to exit after its request pipe closes, before it is killed.
constexpr double kExitGraceSeconds = 2.0;

// Moves `fd` to a number >= 10 with close-on-exec, so posix_spawn's dup2 onto 3 and 4
// never has source == target (which would keep close-on-exec set on some C libraries).
int high_fd(int fd) {
  const int moved = ::fcntl(fd, F_DUPFD_CLOEXEC, 10);
  ::close(fd);
  return moved;
}

void set_nonblocking(int fd) { ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK); }

// CPU time (user + system, every thread) the process has used so far, in seconds: fields
// 14 and 15 of /proc/PID/stat, utime and stime in clock ticks (proc(5)). The fields are
// counted after the last ')', since the command name in parentheses may hold spaces.
// Negative when the file cannot be read.
double process_cpu_s(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t close = text.rfind(')');
  if (close == std::string::npos) return -1;
  std::istringstream fields(text.substr(close + 1));
  std::string skipped;
  for (int field = 3; field <= 13; ++field) fields >> skipped;  // state .. cmajflt
  unsigned long long utime = 0, stime = 0;
  if (!(fields >> utime >> stime)) return -1;
  return double(utime + stime) / double(::sysconf(_SC_CLK_TCK));
}

// The error of a frame whose worker did not answer within `timeout_s`, with the CPU time it
// spent meanwhile (negative: unknown): a worker that computed all along needs a longer
// --frame-timeout or a cheaper preset; one that hardly ran was waiting (a slow file system)
// or starved (a machine busier than the worker count assumes).
std::string timeout_error(double timeout_s, double cpu_s) {
  char text[256];
  if (cpu_s < 0)
    std::snprintf(text, sizeof text, "timed out after %g s (worker killed and replaced; see --frame-timeout)",
                  timeout_s);
  else
    std::snprintf(text, sizeof text,
                  "timed out after %g s, in which the worker used %.1f s of CPU time%s (worker killed and "
                  "replaced; see --frame-timeout)",
                  timeout_s, cpu_s, cpu_s < 0.1 * timeout_s ? ": it was mostly waiting, not computing" : "");
  return text;
}

}  // namespace

nlohmann::json Confinement::to_json() const {
  return nlohmann::json{{"input_roots", input_roots},
                        {"option_roots", option_roots},
                        {"view_roots", view_roots},
                        {"output_root", output_root}};
}

Confinement Confinement::from_json(const nlohmann::json& j) {
  Confinement c;
  if (!j.is_object()) return c;
  auto strings = [&](const char* key, std::vector<std::string>& out) {
    if (j.contains(key) && j[key].is_array())
      for (const auto& s : j[key])
        if (s.is_string()) out.push_back(s.get<std::string>());
  };
  strings("input_roots", c.input_roots);
  strings("option_roots", c.option_roots);
  strings("view_roots", c.view_roots);
  c.output_root = j.value("output_root", std::string());
  return c;
}

std::string signal_description(int sig) {
  const char* abbrev = ::sigabbrev_np(sig);
  const char* text = ::sigdescr_np(sig);
  std::string s = abbrev ? std::string("SIG") + abbrev : "signal " + std::to_string(sig);
  if (text) s += std::string(" (") + text + ")";
  return s;
}

WorkerProcess::WorkerProcess(WorkerLimits limits, std::string executable)
    : limits_(limits), executable_(std::move(executable)) {}

WorkerProcess::~WorkerProcess() { stop(false); }

void WorkerProcess::release() {
  if (pid_ <= 0) return;
  ::close(to_worker_);
  ::close(from_worker_);
  to_worker_ = from_worker_ = -1;
  pid_ = -1;
}

bool WorkerProcess::start(std::string& error) { return pid_ > 0 || spawn(error); }

bool WorkerProcess::spawn(std::string& error) {
  int req[2], resp[2];
  if (::pipe2(req, O_CLOEXEC) != 0) {
    error = std::string("cannot create a pipe for a worker: ") + std::strerror(errno);
    return false;
  }
  if (::pipe2(resp, O_CLOEXEC) != 0) {
    error = std::string("cannot create a pipe for a worker: ") + std::strerror(errno);
    ::close(req[0]);
    ::close(req[1]);
    return false;
  }
  for (int* fd : {&req[0], &req[1], &resp[0], &resp[1]}) *fd = high_fd(*fd);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, 2, 1);  // stray library prints go to stderr
  posix_spawn_file_actions_adddup2(&actions, req[0], 3);
  posix_spawn_file_actions_adddup2(&actions, resp[1], 4);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  for (int s : {SIGPIPE, SIGINT, SIGTERM, SIGHUP, SIGCHLD}) sigaddset(&defaults, s);
  posix_spawnattr_setsigmask(&attr, &none);        // the parent blocks SIGINT/SIGTERM/SIGHUP for sigwait
  posix_spawnattr_setsigdefault(&attr, &defaults);  // and ignores SIGPIPE
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);

  const std::string threads = std::to_string(limits_.threads);
  const std::string memory = std::to_string(limits_.memory_limit_mb);
  const std::string pixels = std::to_string(limits_.max_pixels);
  const std::string parent = std::to_string(::getpid());
  const char* argv[] = {"ssdo",       "worker",       "--threads", threads.c_str(), "--memory-limit",
                        memory.c_str(), "--max-pixels", pixels.c_str(), "--parent", parent.c_str(),
                        nullptr};
  pid_t pid = -1;
  const int rc =
      ::posix_spawn(&pid, executable_.c_str(), &actions, &attr, const_cast<char**>(argv), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(req[0]);
  ::close(resp[1]);
  if (rc != 0) {
    ::close(req[1]);
    ::close(resp[0]);
    error = "cannot start a worker (" + executable_ + "): " + std::strerror(rc);
    return false;
  }
  pid_ = pid;
  to_worker_ = req[1];
  from_worker_ = resp[0];
  set_nonblocking(to_worker_);
  set_nonblocking(from_worker_);
  ++spawns_;
  return true;
}

std::string WorkerProcess::reap_reason() {
  if (pid_ <= 0) return "no worker";
  int status = 0;
  // The worker closed its pipe: it is exiting or has exited. Wait briefly, then kill.
  const Deadline give_up = deadline_in(kExitGraceSeconds);
  pid_t r = 0;
  while ((r = ::waitpid(pid_, &status, WNOHANG)) == 0 && Clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  if (r == 0) {
    ::kill(pid_, SIGKILL);
    r = ::waitpid(pid_, &status, 0);
  }
  std::string reason;
  if (r != pid_) reason = "worker lost";
  else if (WIFSIGNALED(status)) reason = "worker killed by " + signal_description(WTERMSIG(status));
  else if (WIFEXITED(status)) reason = "worker exited with status " + std::to_string(WEXITSTATUS(status));
  else reason = "worker ended";
  ::close(to_worker_);
  ::close(from_worker_);
  to_worker_ = from_worker_ = -1;
  pid_ = -1;
  return reason;
}

void WorkerProcess::stop(bool kill_now) {
  if (pid_ <= 0) return;
  if (kill_now) ::kill(pid_, SIGKILL);
  ::close(to_worker_);  // end of requests: an idle worker exits
  to_worker_ = -1;
  int status = 0;
  const Deadline give_up = deadline_in(kExitGraceSeconds);
  while (::waitpid(pid_, &status, WNOHANG) == 0) {
    if (Clock::now() >= give_up) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ::close(from_worker_);
  from_worker_ = -1;
  pid_ = -1;
}

void read_worker_response(const nlohmann::json& j, WorkerResult& result) {
  // A field of the expected type, else the fallback.
  const auto number = [&](const char* key, double fallback) {
    const auto it = j.find(key);
    return it != j.end() && it->is_number() ? it->get<double>() : fallback;
  };
  const auto text = [](const nlohmann::json& o, const char* key) {
    const auto it = o.find(key);
    return it != o.end() && it->is_string() ? it->get<std::string>() : std::string();
  };
  const auto flag = [&](const char* key) {
    const auto it = j.find(key);
    return it != j.end() && it->is_boolean() && it->get<bool>();
  };
  const auto count = [](const nlohmann::json& o, const char* key) {
    const auto it = o.find(key);
    return it != o.end() && it->is_number_integer() ? int(std::clamp<int64_t>(it->get<int64_t>(), 0, 1 << 30)) : 0;
  };
  // Messages and notes may quote names read from a damaged file: no control characters
  // in logs.
  result.error = printable(text(j, "error"));
  if (!flag("ok") && result.error.empty()) result.error = "the worker reported a failure";
  result.transient = flag("out_of_memory");
  result.times.read_ms = number("read_ms", 0.0);
  result.times.compute_ms = number("compute_ms", 0.0);
  result.times.write_ms = number("write_ms", 0.0);
  result.handled_ms = number("handled_ms", 0.0);
  result.peak_rss_mib = number("peak_rss_mib", 0.0);
  result.page_faults = count(j, "page_faults");
  result.width_px = count(j, "width");
  result.height_px = count(j, "height");
  const auto strings = [&](const char* key, std::vector<std::string>& out) {
    const auto list = j.find(key);
    if (list == j.end() || !list->is_array()) return;
    for (const auto& t : *list)
      if (t.is_string()) out.push_back(printable(t.get<std::string>()));
  };
  strings("terms", result.terms);
  strings("notes", result.notes);
  if (const auto w = j.find("window"); w != j.end() && w->is_object()) {
    result.views_per_side = count(*w, "views");
    result.temporal_per_side = count(*w, "temporal");
    result.window_note = printable(text(*w, "note"));
  }
}

WorkerResult WorkerProcess::run(const WorkerJob& job) {
  WorkerResult result;
  const auto t0 = Clock::now();
  nlohmann::json message{{"input", job.input_path},
                         {"output", job.output_path},
                         {"options", job.options},
                         {"confine", job.confine.to_json()}};
  if (!job.neighbours.empty()) {
    nlohmann::json& list = message["neighbours"] = nlohmann::json::array();
    for (const NeighbourFrame& n : job.neighbours)
      list.push_back({{"path", n.path}, {"offset", n.frame_offset}, {"later", n.computed_later}});
  }
  const std::string request = to_wire(message);
  const Deadline deadline = deadline_in(limits_.frame_timeout_s);
  // A worker may have died while idle; then the request cannot be written: start a new
  // one and send again (once).
  for (int attempt = 0;; ++attempt) {
    std::string error;
    if (pid_ <= 0) {
      if (!spawn(error)) {
        result.error = error;
        return result;
      }
      result.worker_started = true;
    }
    const IoStatus s = write_message(to_worker_, request, deadline);
    if (s == IoStatus::ok) break;
    const std::string reason = reap_reason();
    result.worker_replaced = true;
    if (attempt == 1) {
      result.error = "cannot send the frame to a worker: " + std::string(to_string(s)) + "; " + reason;
      return result;
    }
  }

  const double cpu_at_send_s = process_cpu_s(pid_);
  // A worker that dies or is killed while writing leaves its temp files beside the output.
  const pid_t worker_pid = pid_;
  auto remove_its_temp_files = [&] {
    remove_temp_files_of(std::filesystem::path(job.output_path).parent_path().string(), worker_pid);
  };
  std::string response;
  // The frame's time is counted while this process runs (a suspended job resumes its
  // frames); the reply itself, once it starts, has what is left.
  IoStatus s = wait_readable_running(from_worker_, std::chrono::duration<double>(deadline - Clock::now()).count());
  if (s == IoStatus::ok) s = read_message(from_worker_, response, kMaxResponseBytes, deadline_in(kReplySeconds));
  result.wall_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (s == IoStatus::timeout) {
    const double cpu_now_s = process_cpu_s(pid_);
    ::kill(pid_, SIGKILL);
    reap_reason();
    remove_its_temp_files();
    result.worker_replaced = result.transient = true;
    result.error = timeout_error(limits_.frame_timeout_s,
                                 cpu_at_send_s < 0 || cpu_now_s < 0 ? -1.0 : cpu_now_s - cpu_at_send_s);
    return result;
  }
  if (s != IoStatus::ok) {
    result.error = reap_reason() + " while processing the frame";
    remove_its_temp_files();
    result.worker_replaced = result.transient = true;
    return result;
  }
  const nlohmann::json j = nlohmann::json::parse(response, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    ::kill(pid_, SIGKILL);
    reap_reason();
    remove_its_temp_files();
    result.worker_replaced = true;
    result.error = "the worker sent a malformed response (worker replaced)";
    return result;
  }
  read_worker_response(j, result);
  if (const auto exiting = j.find("exiting"); exiting != j.end() && exiting->is_boolean() && exiting->get<bool>()) {
    // The worker's last words (an uncaught exception).
    reap_reason();
    result.worker_replaced = result.transient = true;
  }
  return result;
}

}  // namespace ssdo
