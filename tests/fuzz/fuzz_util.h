// Helpers shared by the libFuzzer targets of tests/fuzz/.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace ssdo::fuzz {

// The fuzz input as a file the path-based readers can open: an anonymous memory file
// (memfd) seen through /proc/self/fd/N. No disk I/O, nothing left behind. The sidecar
// conventionally beside it ("/proc/self/fd/N.camera.json") never exists.
class MemFile {
 public:
  MemFile(const uint8_t* data, size_t size) {
    fd_ = ::memfd_create("ssdo-fuzz", MFD_CLOEXEC);
    if (fd_ < 0) std::abort();  // the harness, not the product, is broken
    size_t done = 0;
    while (done < size) {
      const ssize_t n = ::write(fd_, data + done, size - done);
      if (n <= 0) std::abort();
      done += size_t(n);
    }
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemFile() { ::close(fd_); }
  MemFile(const MemFile&) = delete;
  MemFile& operator=(const MemFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  int fd_ = -1;
  std::string path_;
};

}  // namespace ssdo::fuzz
