#include "service/file_version.h"

#include "formats/camera_io.h"

namespace ssdo {

bool FileVersion::operator==(const FileVersion& o) const {
  return exists == o.exists && dev == o.dev && ino == o.ino && size == o.size && mtime.tv_sec == o.mtime.tv_sec &&
         mtime.tv_nsec == o.mtime.tv_nsec && ctime.tv_sec == o.ctime.tv_sec && ctime.tv_nsec == o.ctime.tv_nsec;
}

bool later_than(const timespec& a, const timespec& b) {
  return a.tv_sec != b.tv_sec ? a.tv_sec > b.tv_sec : a.tv_nsec > b.tv_nsec;
}

timespec FileVersion::last_change() const { return later_than(ctime, mtime) ? ctime : mtime; }

FileVersion version_of(const std::string& path) {
  FileVersion v;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return v;
  v.exists = true;
  v.regular = S_ISREG(st.st_mode);
  v.dev = st.st_dev;
  v.ino = st.st_ino;
  v.size = st.st_size;
  v.mtime = st.st_mtim;
  v.ctime = st.st_ctim;
  // The link's own time, except for the descriptor names of /proc (each process's own).
  struct stat link {};
  if (path.rfind("/proc/", 0) != 0 && ::lstat(path.c_str(), &link) == 0 && S_ISLNK(link.st_mode) &&
      later_than(link.st_ctim, v.ctime))
    v.ctime = link.st_ctim;
  return v;
}

std::string version_key(const FileVersion& v) {
  if (!v.exists) return "none";
  return std::to_string(v.ino) + ":" + std::to_string(v.size) + ":" + std::to_string(v.mtime.tv_sec) + "." +
         std::to_string(v.mtime.tv_nsec) + ":" + std::to_string(v.ctime.tv_sec) + "." + std::to_string(v.ctime.tv_nsec);
}

std::string frame_version_key(const std::string& frame, const std::string& camera_json) {
  const std::string camera = camera_json.empty() ? sidecar_path_for(frame) : camera_json;
  return version_key(version_of(frame)) + "|" + version_key(version_of(camera));
}

}  // namespace ssdo
