#include "service/watcher.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

#include "service/frame_list.h"

namespace ssdo {

namespace fs = std::filesystem;

DirectoryWatcher::DirectoryWatcher(std::string dir, double poll_s, Report report, Log log)
    : dir_(std::move(dir)), poll_s_(poll_s), report_(std::move(report)), log_(std::move(log)) {}

DirectoryWatcher::~DirectoryWatcher() { stop(); }

namespace {

// IN_CREATE only for links, symbolic or hard (a link is complete when made: it has no
// close; a hard link is a regular file with more than one name, one being written has
// one); a file is reported when closed after writing or moved in.
constexpr uint32_t kFolderEvents =
    IN_CLOSE_WRITE | IN_MOVED_TO | IN_CREATE | IN_DELETE_SELF | IN_MOVE_SELF | IN_ONLYDIR;
bool is_link(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return false;
  return S_ISLNK(st.st_mode) || (S_ISREG(st.st_mode) && st.st_nlink > 1);
}

// While the folder is gone, how often the watcher looks for it besides the parent's events
// (the parent may be replaced too).
constexpr int kLostRetryMs = 1000;

bool is_reported(const std::string& path) { return is_frame_file(path) || !frame_for_sidecar(path).empty(); }

}  // namespace

bool DirectoryWatcher::start(std::string& error) {
  inotify_fd_ = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (inotify_fd_ < 0) {
    error = std::string("inotify: ") + std::strerror(errno);
    return false;
  }
  if ((watch_wd_ = ::inotify_add_watch(inotify_fd_, dir_.c_str(), kFolderEvents)) < 0) {
    error = dir_ + ": cannot watch: " + std::strerror(errno);
    return false;
  }
  watching_ = true;
  // Best effort: without it (an unreadable parent) the retry while lost still works.
  const std::string parent = fs::path(dir_).parent_path().string();
  parent_wd_ = ::inotify_add_watch(inotify_fd_, parent.c_str(), IN_CREATE | IN_MOVED_TO | IN_ONLYDIR);
  if (::pipe2(stop_pipe_, O_CLOEXEC | O_NONBLOCK) != 0) {
    error = std::string("pipe: ") + std::strerror(errno);
    return false;
  }
  scan(false);
  thread_ = std::thread([this] { run(); });
  return true;
}

bool DirectoryWatcher::add_watch() {
  const int wd = ::inotify_add_watch(inotify_fd_, dir_.c_str(), kFolderEvents);
  if (wd < 0) return false;
  watch_wd_ = wd;
  watching_ = true;
  ++reestablished_;
  log_("watch: " + dir_ + " is there again; watching it");
  scan(false);
  return true;
}

void DirectoryWatcher::lose_watch(const char* why) {
  if (watch_wd_ >= 0) ::inotify_rm_watch(inotify_fd_, watch_wd_);  // a moved folder keeps its watch
  watch_wd_ = -1;
  watching_ = false;
  log_("watch: " + dir_ + " " + why + "; nothing is watched until a folder of that name is there again");
}

void DirectoryWatcher::stop() {
  if (thread_.joinable()) {
    const char c = 's';
    (void)!::write(stop_pipe_[1], &c, 1);
    thread_.join();
  }
  for (int* fd : {&inotify_fd_, &stop_pipe_[0], &stop_pipe_[1]})
    if (*fd >= 0) {
      ::close(*fd);
      *fd = -1;
    }
}

void DirectoryWatcher::scan(bool stable_only) {
  std::vector<std::string> frames;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir_, ec))
    if (e.is_regular_file(ec) && is_reported(e.path().string())) frames.push_back(e.path().string());
  if (ec) log_("watch: cannot list " + dir_ + ": " + ec.message());
  std::sort(frames.begin(), frames.end());
  std::map<std::string, std::pair<off_t, timespec>> seen;
  for (const std::string& f : frames) {
    struct stat st {};
    if (::stat(f.c_str(), &st) != 0) continue;
    seen[f] = {st.st_size, st.st_mtim};
    if (stable_only) {
      const auto it = last_seen_.find(f);
      if (it == last_seen_.end() || it->second.first != st.st_size ||
          it->second.second.tv_sec != st.st_mtim.tv_sec || it->second.second.tv_nsec != st.st_mtim.tv_nsec)
        continue;  // new or still changing: look again at the next scan
    }
    report_(f);
  }
  last_seen_.swap(seen);
}

void DirectoryWatcher::run() {
  alignas(inotify_event) char buffer[64 * 1024];
  auto next_poll = std::chrono::steady_clock::now() + std::chrono::duration<double>(poll_s_);
  for (;;) {
    int timeout_ms = watching_ ? -1 : kLostRetryMs;
    if (poll_s_ > 0) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(next_poll - std::chrono::steady_clock::now());
      const int poll_ms = int(std::max<long long>(0, left.count()));
      timeout_ms = timeout_ms < 0 ? poll_ms : std::min(timeout_ms, poll_ms);
    }
    pollfd fds[2] = {{inotify_fd_, POLLIN, 0}, {stop_pipe_[0], POLLIN, 0}};
    const int n = ::poll(fds, 2, timeout_ms);
    if (n < 0 && errno != EINTR) {
      log_(std::string("watch: poll: ") + std::strerror(errno));
      return;
    }
    if (fds[1].revents) return;
    if (!watching_) add_watch();
    if (watching_ && poll_s_ > 0 && std::chrono::steady_clock::now() >= next_poll) {
      scan(true);
      next_poll = std::chrono::steady_clock::now() + std::chrono::duration<double>(poll_s_);
    }
    if (!(fds[0].revents & POLLIN)) continue;
    for (;;) {
      const ssize_t len = ::read(inotify_fd_, buffer, sizeof buffer);
      if (len <= 0) break;
      handle_events(buffer, size_t(len));
    }
  }
}

void DirectoryWatcher::handle_events(char* buffer, size_t size) {
  bool rescan = false;
  const std::string name = fs::path(dir_).filename().string();
  for (size_t at = 0; at < size;) {
    const auto* event = reinterpret_cast<const inotify_event*>(buffer + at);
    at += sizeof(inotify_event) + event->len;
    if (event->mask & IN_Q_OVERFLOW) {
      rescan = true;
    } else if (event->wd == parent_wd_) {
      if (!watching_ && event->len > 0 && (event->mask & IN_ISDIR) && name == event->name) add_watch();
    } else if (event->wd != watch_wd_) {
      continue;  // a watch already given up (its IN_IGNORED, or events of the folder moved away)
    } else if (event->mask & (IN_DELETE_SELF | IN_MOVE_SELF | IN_IGNORED)) {
      lose_watch(event->mask & IN_MOVE_SELF ? "was renamed away" : "was deleted or unmounted");
    } else if (event->len > 0 && !(event->mask & IN_ISDIR)) {
      const std::string path = (fs::path(dir_) / event->name).string();
      if ((event->mask & IN_CREATE) && !is_link(path)) continue;
      if (is_reported(path)) report_(path);
    }
  }
  if (rescan && watching_) {
    log_("watch: event queue overflowed; scanning " + dir_);
    scan(false);
  }
}

}  // namespace ssdo
