#include "service/confined_open.h"

#include <fcntl.h>
#include <linux/openat2.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "service/path_policy.h"

namespace ssdo {

namespace {

// openat2(2) through syscall(2): C libraries before glibc 2.40 have no wrapper.
int openat2_beneath(int root_fd, const std::string& relative, int flags) {
#ifdef SYS_openat2
  open_how how{};
  how.flags = uint64_t(flags | O_CLOEXEC);
  how.resolve = RESOLVE_BENEATH | RESOLVE_NO_SYMLINKS | RESOLVE_NO_MAGICLINKS;
  return int(::syscall(SYS_openat2, root_fd, relative.c_str(), &how, sizeof how));
#else
  (void)root_fd, (void)relative, (void)flags;
  errno = ENOSYS;
  return -1;
#endif
}

}  // namespace

void UniqueFd::reset(int fd) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
}

std::string fd_path(int fd) { return "/proc/self/fd/" + std::to_string(fd); }

// The walk of kernels without openat2: each folder component opened O_NOFOLLOW |
// O_DIRECTORY from the previous one (a symbolic link there fails with ENOTDIR), ".."
// refused, the last component opened O_NOFOLLOW (a symbolic link fails with ELOOP).
int open_beneath_walk(int root_fd, const std::string& relative, int flags) {
  UniqueFd dir(::fcntl(root_fd, F_DUPFD_CLOEXEC, 0));
  size_t begin = 0;
  for (;;) {
    const size_t end = relative.find('/', begin);
    const std::string part = relative.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
    if (part == "..") {
      errno = EXDEV;
      return -1;
    }
    if (end == std::string::npos) {
      if (part.empty() || part == ".") return ::openat(dir.get(), ".", flags | O_CLOEXEC);
      return ::openat(dir.get(), part.c_str(), flags | O_NOFOLLOW | O_CLOEXEC);
    }
    if (!part.empty() && part != ".") {
      const int next = ::openat(dir.get(), part.c_str(), O_PATH | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
      if (next < 0) return -1;
      dir.reset(next);
    }
    begin = end + 1;
  }
}

int open_beneath(int root_fd, const std::string& relative, int flags) {
  const std::string rel = relative.empty() ? "." : relative;
  const int fd = openat2_beneath(root_fd, rel, flags);
  if (fd >= 0 || errno != ENOSYS) return fd;
  return open_beneath_walk(root_fd, rel, flags);
}

namespace {

// Why an open beneath a root failed, for a message.
std::string open_failure(int err) {
  if (err == ELOOP || err == ENOTDIR || err == EXDEV)
    return "a symbolic link in its path changed or points outside the allowed folders; refused";
  return std::strerror(err);
}

// The root of `canonical` among `roots`, and the path below it.
bool split_under_roots(const std::string& canonical, const std::vector<std::string>& roots, std::string& root,
                       std::string& relative) {
  for (const std::string& r : roots) {
    if (!path_is_under(canonical, r)) continue;
    root = r;
    relative = canonical.size() == r.size() ? "" : canonical.substr(r == "/" ? 1 : r.size() + 1);
    return true;
  }
  return false;
}

// Opens `canonical` beneath its root with `flags`; -1 with a message otherwise.
int open_under_roots(const std::string& path, const std::string& canonical, const std::vector<std::string>& roots,
                     int flags, std::string& error) {
  std::string root, relative;
  if (!split_under_roots(canonical, roots, root, relative)) {
    error = path + ": outside the allowed folders (resolves to " + canonical +
            "; a request's files lie under --allow, a watched frame's in the watch folder)";
    return -1;
  }
  const UniqueFd root_fd(::open(root.c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC));
  if (!root_fd) {
    error = root + ": cannot open the allowed folder: " + std::strerror(errno);
    return -1;
  }
  const int fd = open_beneath(root_fd.get(), relative, flags);
  if (fd < 0) error = path + ": " + open_failure(errno);
  return fd;
}

}  // namespace

bool open_confined_file(const std::string& path, const std::vector<std::string>& roots, UniqueFd& fd,
                        std::string& canonical, std::string& error) {
  // O_NONBLOCK: opening a FIFO for reading would wait for a writer (fifo(7)).
  const int flags = O_RDONLY | O_NONBLOCK | O_NOCTTY;
  if (roots.empty()) {
    canonical = path;
    fd.reset(::open(path.c_str(), flags | O_CLOEXEC));
    if (!fd) error = path + ": " + std::strerror(errno);
  } else {
    if (!canonical_path(path, canonical, error)) return false;
    fd.reset(open_under_roots(path, canonical, roots, flags, error));
  }
  if (!fd) return false;
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0 || !S_ISREG(st.st_mode)) {
    error = path + (S_ISDIR(st.st_mode) ? ": a folder, not a file"
                                        : ": not a regular file (a FIFO, socket or device is refused)");
    fd.reset();
    return false;
  }
  return true;
}

bool open_confined_folder(const std::string& path, const std::string& root, UniqueFd& fd, std::string& error) {
  std::string canonical;
  if (!canonical_path(path, canonical, error)) return false;
  fd.reset(open_under_roots(path, canonical, {root}, O_PATH | O_DIRECTORY, error));
  if (!fd && error.find("outside the allowed folders") != std::string::npos)
    error = path + ": outside the output folder " + root;
  return bool(fd);
}

}  // namespace ssdo
