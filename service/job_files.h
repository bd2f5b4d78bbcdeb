// The files of one worker job, opened by the worker itself through service/confined_open.h
// and held open while the frame is read and written: the readers and the writer get
// "/proc/self/fd/N" names of these descriptors, so what was checked is what is read, and
// the output lands in the folder that was checked, whatever is renamed or swapped meanwhile.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "service/confined_open.h"
#include "service/pipeline.h"
#include "service/worker_process.h"

namespace ssdo {

class JobFiles {
 public:
  // Opens the input, its camera file (the request's, else NAME.camera.json when present)
  // and the output's folder, and points `request` at them. False with a message.
  bool open(const Confinement& confine, FrameRequest& request, std::string& error);
  // Opens each neighbour and its NAME.camera.json under the input's roots
  // (NeighbourFrame::open_path, camera_json); a neighbour that cannot be opened is dropped
  // with a note (a view is never an error).
  void open_neighbours(const Confinement& confine, std::vector<NeighbourFrame>& neighbours,
                       std::vector<std::string>& notes);
  // Opens an environment map of the options (before resolve_frame_options) and replaces
  // `env_path` with the opened file's name.
  bool open_environment(const Confinement& confine, std::string& env_path, std::string& error);
  // `message` with the descriptor names replaced by the names the request gave.
  std::string named(std::string message) const;

 private:
  // Opens `path` confined to `roots`; `path` becomes the descriptor's name.
  bool open_file(std::string& path, const std::vector<std::string>& roots, std::string& error);
  // Opens NAME.camera.json beside `frame` when there is one (camera_json = its descriptor's
  // name; left as it is when there is none).
  bool open_sidecar(const std::string& frame, const std::vector<std::string>& roots, std::string& camera_json,
                    std::string& error);
  bool open_camera(const Confinement& confine, const std::string& input, FrameRequest& request, std::string& error);
  bool open_output_folder(const Confinement& confine, std::string& output, std::string& error);

  std::vector<UniqueFd> fds_;
  std::vector<std::pair<std::string, std::string>> names_;  // descriptor name -> given name
};

}  // namespace ssdo
