// `ssdo serve`: a long-running service. Frames dropped into --watch and frames asked for
// on --socket are computed by worker processes (service/frame_service.h); SIGTERM,
// SIGINT or SIGHUP stop it gracefully (no new work, frames in flight finish, exit 0).
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <thread>

#include <CLI/CLI.hpp>

#include "service/cli_options.h"
#include "service/commands.h"
#include "service/frame_list.h"
#include "service/frame_service.h"
#include "service/parallelism.h"
#include "service/path_policy.h"
#include "service/socket_server.h"
#include "service/watcher.h"

namespace ssdo {

namespace fs = std::filesystem;

namespace {

// One service per output folder: OUT/.ssdo-serve.lock held with flock(2) (LOCK_EX |
// LOCK_NB) for the service's life, so a second instance cannot remove the first one's
// spool or race it for the same outputs. The kernel drops the lock when the process ends,
// kill -9 included; the descriptor is close-on-exec, so workers never hold it.
int lock_output_folder(const std::string& out_dir, std::string& error) {
  const std::string path = (fs::path(out_dir) / ".ssdo-serve.lock").string();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd < 0) {
    error = path + ": cannot open the lock file: " + std::strerror(errno);
    return -1;
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    char pid[32] = {};
    (void)!::pread(fd, pid, sizeof pid - 1, 0);
    error = out_dir + ": another ssdo serve uses this output folder (pid " + std::string(pid) +
            ", lock " + path + "); give each instance its own -o";
    ::close(fd);
    return -1;
  }
  const std::string text = std::to_string(::getpid());
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, text.data(), text.size(), 0) < 0) {
    // The pid is for people reading the refusal; the lock holds without it.
  }
  return fd;
}

// The output folder and its lock, made again when they were removed while the service
// runs (a frame's output would fail, and a second instance could take the folder): false
// when another instance holds the new lock by then (`note` says so). `note` also tells of
// a folder made again.
bool keep_output_folder(const std::string& out_dir, int& lock_fd, std::string& note) {
  note.clear();
  struct stat held {}, now {};
  const std::string path = (fs::path(out_dir) / ".ssdo-serve.lock").string();
  if (::fstat(lock_fd, &held) == 0 && ::lstat(path.c_str(), &now) == 0 && held.st_dev == now.st_dev &&
      held.st_ino == now.st_ino)
    return true;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  std::string error;
  const int fd = lock_output_folder(out_dir, error);
  if (fd < 0) {
    note = "the output folder " + out_dir + " was removed, and " + error;
    return false;
  }
  ::close(lock_fd);
  lock_fd = fd;
  note = "the output folder " + out_dir + " (or its lock) was removed: made again and locked";
  return true;
}

// The outermost folder create_directories(`path`) would make, or "" when `path` exists.
fs::path first_missing_folder(const std::string& path) {
  std::error_code ec;
  fs::path missing;
  for (fs::path p = fs::absolute(path, ec).lexically_normal(); !p.empty() && !fs::exists(p, ec);
       p = p.parent_path()) {
    if (p.filename().empty()) continue;  // "out/" is "out"
    missing = p;
    if (p == p.parent_path()) break;
  }
  return missing;
}

// A start that fails once it holds the output folder's lock leaves nothing it made: the
// spool, and when the output folder was made for this start, its lock and the folders made
// (those still empty).
void undo_start(const std::string& out_dir, const fs::path& made_from, int lock_fd) {
  std::error_code ec;
  fs::remove_all(fs::path(out_dir) / ".ssdo-spool", ec);
  if (made_from.empty()) return;
  fs::remove(fs::path(out_dir) / ".ssdo-serve.lock", ec);
  if (lock_fd >= 0) ::close(lock_fd);
  for (fs::path p = out_dir; fs::remove(p, ec) && p != made_from && p.has_parent_path(); p = p.parent_path()) {
  }
}

}  // namespace

int run_serve(const ServeArgs& args) {
  auto usage = [](const std::string& message) {
    std::cerr << "ssdo serve: " << message << "\n";
    return 2;
  };
  if (args.watch_dir.empty() && args.socket_path.empty()) return usage("give --watch DIR, --socket PATH or both");
  std::error_code ec;
  std::string out_dir, error;
  std::string watch_dir;
  if (!args.watch_dir.empty() && (!canonical_path(args.watch_dir, watch_dir, error) || !fs::is_directory(watch_dir)))
    return usage("--watch " + args.watch_dir + ": not a folder");
  std::vector<std::string> allow;
  for (const std::string& root : args.allow) {
    std::string canonical;
    if (!canonical_path(root, canonical, error)) return usage("--allow " + error);
    allow.push_back(canonical);
  }
  if (allow.empty() && !watch_dir.empty()) allow.push_back(watch_dir);
  mode_t mode = 0;
  try {
    size_t used = 0;
    mode = mode_t(std::stoul(args.socket_mode, &used, 8));
    if (used != args.socket_mode.size() || mode > 0777) throw std::invalid_argument(args.socket_mode);
  } catch (const std::exception&) {
    return usage("--socket-mode " + args.socket_mode + ": expected octal permissions such as 0600");
  }

  // The arguments checked, the output folder is made (undo_start removes it again when the
  // start fails) and locked.
  const fs::path made_from = first_missing_folder(args.out_dir);
  fs::create_directories(args.out_dir, ec);
  if (ec || !canonical_path(args.out_dir, out_dir, error))
    return usage("cannot create the output folder " + args.out_dir + (ec ? ": " + ec.message() : ""));
  int lock_fd = lock_output_folder(out_dir, error);
  if (lock_fd < 0) {  // the folder is another instance's
    std::cerr << "ssdo serve: " << error << "\n";
    return 1;
  }
  // Inline frames are spooled here (with a socket only); leftovers of a killed run are
  // removed.
  const std::string spool = (fs::path(out_dir) / ".ssdo-spool").string();
  fs::remove_all(spool, ec);
  if (!args.socket_path.empty()) make_private_folder(spool, ec);
  if (const int n = remove_stale_temp_files(out_dir); n > 0)
    std::cout << "removed " << n << " temp files of an interrupted run in " << out_dir << "\n";

  // SIGINT / SIGTERM / SIGHUP (the terminal or ssh session that started the service
  // closed) are taken by this thread with sigwait: blocked before any thread starts, so
  // every thread inherits the mask; no handler, no global flag.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stop_signals, s);
  ::pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  ::signal(SIGPIPE, SIG_IGN);

  const Parallelism plan = plan_parallelism(args.jobs, args.options.compute.threads, true);
  FrameServiceOptions service_options;
  service_options.out_dir = out_dir;
  service_options.watch_dir = watch_dir;
  service_options.watch_options = to_json(args.options);
  service_options.workers = plan.workers;
  service_options.limits = args.limits;
  service_options.limits.threads = plan.threads_per_frame;
  service_options.queue_capacity = args.queue_capacity;
  service_options.retries = args.retries;
  FrameService frames(service_options);

  // Constructed now (started below, after the workers) so that stats can report on it.
  std::unique_ptr<DirectoryWatcher> watcher;
  if (!watch_dir.empty())
    watcher = std::make_unique<DirectoryWatcher>(
        watch_dir, args.poll_s, [&](const std::string& path) { frames.enqueue_watched(path); },
        [](const std::string& line) { std::cout << printable(line) << "\n" << std::flush; });

  std::unique_ptr<SocketServer> server;
  if (!args.socket_path.empty()) {
    SocketServerOptions o;
    o.path = args.socket_path;
    o.mode = mode;
    o.allow_roots = allow;
    o.out_dir = out_dir;
    o.spool_dir = spool;
    o.watch_dir = watch_dir;
    o.limits = args.protocol;
    o.client_timeout_s = args.client_timeout_s;
    o.frame_timeout_s = args.limits.frame_timeout_s;
    o.max_clients = args.max_clients;
    o.max_spool_bytes = args.max_spool_mb << 20;
    o.default_options = to_json(args.options);
    if (watcher)
      o.watch_status = [w = watcher.get(), watch_dir] {
        const DirectoryWatcher::Status st = w->status();
        return nlohmann::json{
            {"dir", watch_dir}, {"state", st.watching ? "watching" : "lost"}, {"reestablished", st.reestablished}};
      };
    server = std::make_unique<SocketServer>(o, frames);
    if (!server->bind(error)) {
      undo_start(out_dir, made_from, lock_fd);
      return usage(error);
    }
  }
  frames.start();
  if (server) server->start();
  if (watcher && !watcher->start(error)) {
    if (server) server->stop();
    frames.stop();
    undo_start(out_dir, made_from, lock_fd);
    std::cerr << "ssdo serve: " << error << "\n";
    return 1;
  }
  std::cout << "ssdo serve: ready" << (watch_dir.empty() ? "" : "; watching " + watch_dir)
            << (args.socket_path.empty() ? "" : "; socket " + args.socket_path) << "; output " << out_dir << "; "
            << plan.workers << " workers x " << plan.threads_per_frame << " threads\n"
            << std::flush;

  // Until a stop signal; every second, the output folder is checked (keep_output_folder).
  int sig = 0;
  std::string reason;
  bool folder_lost = false;
  for (const timespec tick{1, 0}; reason.empty();) {
    sig = ::sigtimedwait(&stop_signals, nullptr, &tick);
    if (sig > 0) {
      reason = sig == SIGINT ? "SIGINT" : sig == SIGHUP ? "SIGHUP" : "SIGTERM";
      break;
    }
    std::string note;
    folder_lost = !keep_output_folder(out_dir, lock_fd, note);
    if (folder_lost) reason = note;
    else if (!note.empty()) std::cout << "ssdo serve: " << note << "\n" << std::flush;
  }
  std::cout << "ssdo serve: " << reason
            << ": stopping (no new frames; frames in flight finish; a second signal stops at once)\n"
            << std::flush;
  // A second signal: the user will not wait for the frames in flight. The workers die with
  // this process (PR_SET_PDEATHSIG); the next start removes the socket, spool and temp files.
  std::thread([stop_signals] {
    int again = 0;
    while (::sigwait(&stop_signals, &again) != 0) {
    }
    std::cout << "ssdo serve: stopped at once (a second signal): frames in flight abandoned\n" << std::flush;
    std::_Exit(128 + again);
  }).detach();
  if (server) server->stop_accepting();
  if (watcher) watcher->stop();
  frames.stop();
  if (server) server->stop();
  if (!folder_lost) fs::remove_all(spool, ec);  // else the spool is the other instance's now
  const ServiceStats s = frames.stats();
  std::cout << "ssdo serve: stopped; done " << s.frames_done << ", failed " << s.frames_failed << ", skipped "
            << s.frames_skipped << "\n"
            << std::flush;
  return folder_lost ? 1 : 0;
}

Command register_serve(CLI::App& app) {
  struct State {
    ServeArgs serve;
    std::string config;
    size_t max_inline_mb = 0;
  };
  auto st = std::make_shared<State>();
  ServeArgs& s = st->serve;
  st->max_inline_mb = s.protocol.max_inline_bytes >> 20;
  CLI::App* cmd = app.add_subcommand(
      "serve", "Run as a service: compute every frame dropped into --watch (and those already there "
               "without output) and answer requests on --socket; SIGTERM/SIGINT/SIGHUP stop it gracefully");
  cmd->add_option("--watch", s.watch_dir, "Folder to watch for frames (*.exr)")->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--out", s.out_dir, "Output folder: NAME.ssdo.exr, or NAME.error.json")->required();
  cmd->add_option("--poll", s.poll_s,
                  "Also rescan --watch every SECONDS (network file systems, where inotify sees nothing)")
      ->check(seconds_in(0.0, 86400.0));
  cmd->add_option("--socket", s.socket_path, "Unix domain socket to serve requests on");
  cmd->add_option("--socket-mode", s.socket_mode, "Permissions of the socket (octal)")->capture_default_str();
  cmd->add_option("--allow", s.allow,
                  "Folder socket requests may read frames (and camera/environment files) from; "
                  "repeatable (default: the --watch folder)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--queue", s.queue_capacity, "Socket requests waiting at most; beyond: busy")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--max-clients", s.max_clients, "Socket connections at once; beyond: busy")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  cmd->add_option("--client-timeout", s.client_timeout_s,
                  "Seconds a client has to send a whole request (inline frame included) or take a reply")
      ->check(seconds_in(0.001, 86400.0))
      ->capture_default_str();
  cmd->add_option("--max-request-bytes", s.protocol.max_header_bytes, "Largest JSON request header")
      ->check(CLI::Range(size_t(64), size_t(1) << 30))
      ->capture_default_str();
  cmd->add_option("--max-inline-mb", st->max_inline_mb, "Largest inline frame, MiB")
      ->check(CLI::Range(size_t(1), size_t(1) << 16))
      ->capture_default_str();
  cmd->add_option("--retries", s.retries,
                  "Attempts again, on a new worker, of a frame whose worker was killed, timed out or ran "
                  "out of memory")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  cmd->add_option("--max-spool-mb", s.max_spool_mb,
                  "Disk the inline frames being served may take together, MiB; beyond: busy")
      ->check(CLI::Range(size_t(1), size_t(1) << 24))
      ->capture_default_str();
  cmd->add_option("--config", st->config, "JSON file of frame options (as for process)")->check(CLI::ExistingFile);
  add_frame_options(*cmd, s.options);
  add_worker_limits(*cmd, s.jobs, s.limits);
  return {cmd, [st, cmd] {
            st->serve.protocol.max_inline_bytes = st->max_inline_mb << 20;
            std::string error;
            if (!frame_options_over_config(*cmd, st->config, st->serve.options, error)) return usage_error(error);
            return run_serve(st->serve);
          }};
}

}  // namespace ssdo
