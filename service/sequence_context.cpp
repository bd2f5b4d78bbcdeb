#include "service/sequence_context.h"

#include <algorithm>
#include <filesystem>
#include <set>
#include <vector>

#include "service/frame_inputs.h"
#include "service/view_selection.h"

namespace ssdo {

namespace {

// A camera from a bare --fov has no world: its "world" is its own view space.
bool has_world(const FrameInfo& info) { return info.camera_source.rfind("--fov", 0) != 0; }

std::string file_name(const std::string& path) { return std::filesystem::path(path).filename().string(); }

// What identifies the read options whole frames were read with (a request with other
// options reads its frame again).
std::string read_key(const ReadOptions& r) {
  const ChannelMapping& m = r.mapping;
  // Not camera_json: a frame's own sidecar (each frame its own) is not a read option of the batch.
  std::string key = r.part + "|" + std::to_string(int(r.depth_kind)) + "|" +
                    (r.fov_x_deg ? std::to_string(*r.fov_x_deg) : "") + "|" + m.depth + "|" + m.normal + "|" +
                    m.position + "|" + m.albedo + "|" + m.lighting + "|" + std::to_string(int(m.normal_space)) +
                    std::to_string(int(m.position_space)) + std::to_string(r.read_normals) +
                    std::to_string(r.read_positions) + std::to_string(r.read_albedo) +
                    std::to_string(r.read_lighting) + std::to_string(r.read_references);
  for (const auto& [name, channel] : m.references) key += "|" + name + "=" + channel;
  return key;
}

// A neighbour's read: the frame's options with the neighbour's own camera (its sidecar).
ReadOptions neighbour_read(const NeighbourFrame& n, const ReadOptions& read) {
  ReadOptions r = read;
  r.camera_json = n.camera_json;
  return r;
}

}  // namespace

float median_foreground_depth(const cv::Mat& depth_view, const cv::Mat& mask) {
  std::vector<float> depths;
  for (int y = 0; y < depth_view.rows; y += 4) {
    const float* d = depth_view.ptr<float>(y);
    const uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < depth_view.cols; x += 4)
      if (m[x]) depths.push_back(d[x]);
  }
  if (depths.empty()) return 0;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  return depths[depths.size() / 2];
}

ReadResult SequenceContext::read(const FrameRequest& request, const ReadOptions& read) {
  if (request.views_per_side <= 0 || request.neighbours.empty()) {
    cache_.clear();
    return read_frame(request.input_path, read);
  }
  if (const std::string key = read_key(read); key != read_key_) {
    cache_.clear();
    read_key_ = key;
  }
  ReadResult frame;
  const std::string& name = request.input_name.empty() ? request.input_path : request.input_name;
  Entry& self = cache_[name];
  if (self.whole) {
    frame = std::move(*self.whole);
    self.whole.reset();
  } else {
    frame = read_frame(request.input_path, read);
    ++reads_.whole;
  }
  ++reads_.frames;
  if (frame.ok()) {
    // The frame's depth image is shared, not copied: compute_frame releases only its own
    // reference.
    self.view = DepthView{frame.gbuffer.camera, frame.gbuffer.depth_view, file_name(name)};
    self.camera = frame.gbuffer.camera;
    self.camera_has_world = has_world(frame.info);
    if (self.camera_has_world)
      attach_views(request, read, frame);
    else
      frame.info.notes.push_back("views: none (the frame's camera has no world transform to relate others to)");
  }
  keep_window(request);
  return frame;
}

SequenceContext::Entry& SequenceContext::candidate(const NeighbourFrame& n, const ReadOptions& read) {
  Entry& e = cache_[n.path];
  if (e.camera || !e.error.empty()) return e;
  const ReadResult header = inspect_gbuffer(n.open_path.empty() ? n.path : n.open_path, neighbour_read(n, read));
  ++reads_.headers;
  if (!header.ok()) {
    e.error = header.error;
    return e;
  }
  e.camera = header.gbuffer.camera;
  e.camera_has_world = has_world(header.info);
  return e;
}

bool SequenceContext::load_view(const NeighbourFrame& n, const ReadOptions& read, Entry& e) {
  if (e.view) return true;
  const std::string& path = n.open_path.empty() ? n.path : n.open_path;
  ReadResult r = n.computed_later ? read_frame(path, neighbour_read(n, read))
                                  : read_gbuffer(path, depth_only(neighbour_read(n, read)));
  ++(n.computed_later ? reads_.whole : reads_.depth_only);
  if (!r.ok()) {
    e.error = r.error;
    return false;
  }
  e.view = DepthView{r.gbuffer.camera, r.gbuffer.depth_view, file_name(n.path)};
  if (n.computed_later) e.whole = std::move(r);
  return true;
}

void SequenceContext::attach_views(const FrameRequest& request, const ReadOptions& read, ReadResult& frame) {
  std::vector<ViewCandidate> candidates;
  std::vector<const NeighbourFrame*> sources;
  FrameInfo& info = frame.info;
  for (const NeighbourFrame& n : request.neighbours) {
    Entry& e = candidate(n, read);
    if (!e.camera) {
      info.notes.push_back(file_name(n.path) + ": skipped as a view (" + e.error + ")");
      continue;
    }
    candidates.push_back({file_name(n.path), n.frame_offset, e.camera_has_world, e.camera->width_px,
                          e.camera->height_px, e.camera->view_to_world});
    sources.push_back(&n);
  }
  const GBuffer& g = frame.gbuffer;
  ViewSelectionSettings settings;
  settings.views_per_side = request.views_per_side;
  const ViewChoice choice = select_views(g.camera.view_to_world, g.width_px(), g.height_px(),
                                         median_foreground_depth(g.depth_view, g.mask), candidates, settings);
  info.notes.insert(info.notes.end(), choice.notes.begin(), choice.notes.end());
  std::string names;
  for (size_t i : choice.chosen) {
    Entry& e = cache_[sources[i]->path];
    if (!load_view(*sources[i], read, e)) {
      info.notes.push_back(candidates[i].name + ": skipped as a view (" + e.error + ")");
      continue;
    }
    frame.gbuffer.views.push_back(*e.view);
    names += " " + e.view->name;
  }
  info.notes.push_back("views:" + (names.empty() ? std::string(" none") : names) + " (read " +
                       std::to_string(reads_.whole + reads_.depth_only) + " files for " +
                       std::to_string(reads_.frames) + " frames: " + std::to_string(reads_.whole) + " whole, " +
                       std::to_string(reads_.depth_only) + " depth only; " + std::to_string(reads_.headers) +
                       " headers)");
}

void SequenceContext::keep_window(const FrameRequest& request) {
  std::set<std::string> window{request.input_name.empty() ? request.input_path : request.input_name};
  for (const NeighbourFrame& n : request.neighbours) window.insert(n.path);
  for (auto it = cache_.begin(); it != cache_.end();) it = window.count(it->first) ? std::next(it) : cache_.erase(it);
}

}  // namespace ssdo
