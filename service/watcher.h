// Watching a folder for new frames (non-recursive), for `ssdo serve --watch`.
// - At start: every frame already there is reported (the service skips finished ones).
// - inotify IN_CLOSE_WRITE and IN_MOVED_TO only: a frame is reported when its writer
//   closes it or when it is renamed into place, never when it is created (a half-written
//   file is never read). The watch is added before the first scan, so nothing falls in
//   between.
// - IN_Q_OVERFLOW (the kernel dropped events): the folder is scanned again.
// - poll_s > 0, for network file systems where inotify sees nothing: the folder is also
//   scanned every poll_s seconds; a frame is reported once its size and modification time
//   are the same on two consecutive scans (a file still being written is left alone).
// - Camera sidecars (NAME.camera.json) are reported like frames (the service maps them
//   to their frame).
// - The folder deleted, or renamed away (IN_DELETE_SELF, IN_MOVE_SELF, IN_IGNORED): the
//   watch is "lost" and logged; a watch on the parent folder (IN_CREATE, IN_MOVED_TO)
//   and a retry every second while lost re-add it as soon as a folder of that name is
//   there again, then scan it. The renamed folder is no longer watched. status() says
//   which, for the service's stats.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <ctime>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <utility>

namespace ssdo {

class DirectoryWatcher {
 public:
  using Report = std::function<void(const std::string& path)>;
  using Log = std::function<void(const std::string& line)>;
  DirectoryWatcher(std::string dir, double poll_s, Report report, Log log);
  ~DirectoryWatcher();  // stop()
  DirectoryWatcher(const DirectoryWatcher&) = delete;
  DirectoryWatcher& operator=(const DirectoryWatcher&) = delete;

  // Adds the watch, reports the frames already there, starts the thread. False with a
  // message when the folder cannot be watched.
  bool start(std::string& error);
  void stop();

  struct Status {
    bool watching = false;  // false: the folder is gone and the watch waits for it
    long reestablished = 0; // times the folder came back and was watched again
  };
  Status status() const { return {watching_.load(), reestablished_.load()}; }

 private:
  void run();
  void scan(bool stable_only);
  void handle_events(char* buffer, size_t size);
  bool add_watch();
  void lose_watch(const char* why);

  const std::string dir_;
  const double poll_s_;
  const Report report_;
  const Log log_;
  int inotify_fd_ = -1;
  int watch_wd_ = -1, parent_wd_ = -1;
  std::atomic<bool> watching_{false};
  std::atomic<long> reestablished_{0};
  int stop_pipe_[2] = {-1, -1};
  std::thread thread_;
  std::map<std::string, std::pair<off_t, timespec>> last_seen_;  // poll scans: size, mtime
};

}  // namespace ssdo
