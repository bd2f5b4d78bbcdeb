// Opening a file a request names, so that the check and the use are the same open: the
// file's canonical path (realpath(3)) must lie under an allowed root, and the root's
// descriptor is then opened and the rest of the path walked from it with no symbolic link
// followed (openat2(2) RESOLVE_BENEATH | RESOLVE_NO_SYMLINKS | RESOLVE_NO_MAGICLINKS, or,
// on kernels before 5.6, one openat(2) O_NOFOLLOW per component). A symbolic link swapped
// into the path after the check is refused at the open instead of followed; a symbolic link
// already there is followed by realpath and allowed only when its target lies under a root
// too (docs/service.md, "Confinement").
//
// Files are opened O_NONBLOCK and must be regular files (fstat(2)): a FIFO or a device is
// refused before anything reads it. The caller keeps the descriptor and reads through
// fd_path(fd) ("/proc/self/fd/N", proc(5)), which names the opened file itself.
#pragma once

#include <string>
#include <vector>

namespace ssdo {

// An owned descriptor (closed on destruction).
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() { reset(); }
  UniqueFd(UniqueFd&& o) noexcept : fd_(o.release()) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = o.release();
    }
    return *this;
  }
  int get() const { return fd_; }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }
  void reset(int fd = -1);
  explicit operator bool() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

// "/proc/self/fd/N": a name for the already-open file (or folder) `fd`.
std::string fd_path(int fd);

// Opens `relative` (no leading '/') beneath the folder `root_fd` with no symbolic link
// and no ".." above it followed. `flags` are open(2) flags (O_CLOEXEC is added). -1 with
// errno set on failure (ELOOP or EXDEV for a symbolic link or an escape).
int open_beneath(int root_fd, const std::string& relative, int flags);
// The same by a walk of openat(2) O_NOFOLLOW per component: open_beneath's way on kernels
// without openat2 (ENOSYS), exposed for its tests.
int open_beneath_walk(int root_fd, const std::string& relative, int flags);

// Opens the regular file `path` for reading. With `roots` (canonical folders), its
// canonical path must lie under one of them and is opened as above; with none (the
// administrator's own files: the batch, the service's command line), `path` is opened
// as given. `canonical` = the path opened. False with a message naming `path` and the
// reason (missing, outside the roots, a symbolic link at open time, not a regular file).
bool open_confined_file(const std::string& path, const std::vector<std::string>& roots, UniqueFd& fd,
                        std::string& canonical, std::string& error);

// Opens the folder `path` (O_PATH | O_DIRECTORY), whose canonical path must lie under
// `root` (a canonical folder), for writing into it with openat(2) / renameat(2) or through
// fd_path(). False with a message naming `path`.
bool open_confined_folder(const std::string& path, const std::string& root, UniqueFd& fd, std::string& error);

}  // namespace ssdo
