#include "service/job_files.h"

#include <sys/stat.h>

#include <cctype>
#include <filesystem>

#include "formats/camera_io.h"

namespace ssdo {

namespace fs = std::filesystem;

bool JobFiles::open_file(std::string& path, const std::vector<std::string>& roots, std::string& error) {
  UniqueFd fd;
  std::string canonical;
  if (!open_confined_file(path, roots, fd, canonical, error)) return false;
  const std::string name = fd_path(fd.get());
  names_.emplace_back(name, path);
  fds_.push_back(std::move(fd));
  path = name;
  return true;
}

bool JobFiles::open_sidecar(const std::string& frame, const std::vector<std::string>& roots, std::string& camera_json,
                            std::string& error) {
  // The sidecar beside a frame obeys the frame's roots. lstat: a symbolic link or a FIFO
  // there is opened (and refused) like any other sidecar, not skipped.
  std::string sidecar = sidecar_path_for(frame);
  struct stat st {};
  if (::lstat(sidecar.c_str(), &st) != 0) return true;
  if (!open_file(sidecar, roots, error)) return false;
  camera_json = sidecar;
  return true;
}

bool JobFiles::open_camera(const Confinement& confine, const std::string& input, FrameRequest& request,
                           std::string& error) {
  if (!request.read.camera_json.empty()) return open_file(request.read.camera_json, confine.option_roots, error);
  return open_sidecar(input, confine.input_roots, request.read.camera_json, error);
}

bool JobFiles::open_output_folder(const Confinement& confine, std::string& output, std::string& error) {
  if (confine.output_root.empty() || output.empty()) return true;
  const fs::path p(output);
  const std::string folder = p.has_parent_path() ? p.parent_path().string() : ".";
  UniqueFd fd;
  if (!open_confined_folder(folder, confine.output_root, fd, error)) return false;
  const std::string name = fd_path(fd.get());
  names_.emplace_back(name, folder);
  fds_.push_back(std::move(fd));
  output = name + "/" + p.filename().string();
  return true;
}

bool JobFiles::open(const Confinement& confine, FrameRequest& request, std::string& error) {
  const std::string input = request.input_path;
  request.input_name = input;
  if (!open_file(request.input_path, confine.input_roots, error)) return false;
  // The reader's own sidecar name for the descriptor, in its messages, is the input's.
  names_.insert(names_.begin(), {request.input_path + ".camera.json", sidecar_path_for(input)});
  return open_camera(confine, input, request, error) && open_output_folder(confine, request.output_path, error);
}

void JobFiles::open_neighbours(const Confinement& confine, std::vector<NeighbourFrame>& neighbours,
                               std::vector<std::string>& notes) {
  std::vector<NeighbourFrame> opened;
  for (NeighbourFrame n : neighbours) {
    std::string path = n.path, camera_json, error;
    const std::vector<std::string>& roots = confine.view_roots.empty() ? confine.input_roots : confine.view_roots;
    if (!open_file(path, roots, error) || !open_sidecar(n.path, roots, camera_json, error)) {
      notes.push_back(n.path + ": skipped as a view (" + error + ")");
      continue;
    }
    n.open_path = path;
    n.camera_json = camera_json;
    opened.push_back(std::move(n));
  }
  neighbours = std::move(opened);
}

bool JobFiles::open_environment(const Confinement& confine, std::string& env_path, std::string& error) {
  return env_path.empty() || open_file(env_path, confine.option_roots, error);
}

std::string JobFiles::named(std::string message) const {
  for (const auto& [name, given] : names_) {
    // "/proc/self/fd/1" must not match the start of "/proc/self/fd/12".
    for (size_t at = message.find(name); at != std::string::npos; at = message.find(name, at)) {
      const size_t end = at + name.size();
      if (end < message.size() && std::isdigit(static_cast<unsigned char>(message[end]))) {
        at = end;
        continue;
      }
      message.replace(at, name.size(), given);
      at += given.size();
    }
  }
  return message;
}

}  // namespace ssdo
