// One version of a file, as stat(2) describes it: what tells a rewritten or replaced input
// from the one read before, whatever the clock says.
#pragma once

#include <sys/stat.h>

#include <string>

namespace ssdo {

struct FileVersion {
  bool exists = false;
  bool regular = false;  // a regular file (after links), not a folder, FIFO or device
  dev_t dev = 0;
  ino_t ino = 0;
  off_t size = 0;
  timespec mtime{}, ctime{};
  bool operator==(const FileVersion& o) const;
  // The later of the modification and change times. A copy that keeps the source's times
  // (cp -p, rsync -t) or a rename into place sets an old mtime but a new ctime, so both count.
  timespec last_change() const;
};

// Whether `a` is strictly later than `b`.
bool later_than(const timespec& a, const timespec& b);

// stat(2) of `path` (following links: a "/proc/self/fd/N" name gives the file the descriptor
// holds, not a name that may have been swapped since). When `path` itself is a symbolic
// link (a frame published as a link to one version of a render), its own change time counts
// too: pointing it at another, older file is a change of the frame.
FileVersion version_of(const std::string& path);

// One string for a version, to remember it: inode, size, modification and change times
// ("none" for a missing file).
std::string version_key(const FileVersion& v);

// The version of a frame as a worker reads it: the file's and its camera file's
// (`camera_json`, or the sidecar beside the frame when empty: formats/camera_io.h).
std::string frame_version_key(const std::string& frame, const std::string& camera_json = {});

}  // namespace ssdo
