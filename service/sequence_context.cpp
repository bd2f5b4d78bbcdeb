#include "service/sequence_context.h"

#include <algorithm>
#include <filesystem>
#include <set>
#include <vector>

#include "service/file_version.h"
#include "service/frame_inputs.h"
#include "service/view_selection.h"

namespace ssdo {

namespace {

// The frame's name in its sequence (FrameRequest::input_name, else its path): its key in the
// cache and in the neighbour lists.
const std::string& sequence_name(const FrameRequest& request) {
  return request.input_name.empty() ? request.input_path : request.input_name;
}

// A camera from a bare --fov has no world: its "world" is its own view space.
bool has_world(const FrameInfo& info) { return info.camera_source.rfind("--fov", 0) != 0; }

std::string file_name(const std::string& path) { return std::filesystem::path(path).filename().string(); }

// "1 frame", "3 frames".
std::string counted(int64_t n, const std::string& noun) {
  return std::to_string(n) + " " + noun + (n == 1 ? "" : "s");
}

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
  if ((request.views_per_side <= 0 && request.temporal_per_side <= 0) || request.neighbours.empty()) {
    cache_.clear();
    return read_frame(request.input_path, read);
  }
  ++reads_.frames;
  ReadResult frame = read_in_window(request, read);
  keep_window(request);
  return frame;
}

ReadResult SequenceContext::read_in_window(const FrameRequest& request, const ReadOptions& read) {
  if (const std::string key = read_key(read); key != read_key_) {
    cache_.clear();
    read_key_ = key;
  }
  ReadResult frame;
  const std::string& name = sequence_name(request);
  Entry& self = cache_[name];
  if (self.raw_whole && self.raw_info) {
    // Computed already as a temporal neighbour: compute() finishes it (its images are shared).
    frame.gbuffer = self.raw_whole->gbuffer;
    frame.info = *self.raw_info;
    return frame;
  }
  if (self.whole) {
    frame = std::move(*self.whole);
    self.whole.reset();
  } else {
    frame = read_frame(request.input_path, read);
    ++reads_.whole;
  }
  if (frame.ok()) {
    // The frame's depth image is shared, not copied: compute_frame releases only its own
    // reference.
    const ReadOptions as_view = view_reads_for(request, read, !frame.gbuffer.lighting.empty());
    self.view = DepthView{frame.gbuffer.camera, frame.gbuffer.depth_view, file_name(name)};
    if (as_view.read_albedo) self.view->albedo = frame.gbuffer.albedo;
    if (as_view.read_lighting) self.view->lighting = frame.gbuffer.lighting;
    self.view_read = read_key(as_view);
    self.camera = frame.gbuffer.camera;
    self.camera_has_world = has_world(frame.info);
    if (request.views_per_side <= 0) return frame;
    if (self.camera_has_world)
      attach_views(request, read, frame);
    else
      frame.info.notes.push_back("views: none (the frame's camera has no world transform to relate others to)");
  }
  return frame;
}

void SequenceContext::clear() {
  cache_.clear();
  if (store_) store_->clear();
}

void SequenceContext::use_settings(const std::string& key) {
  if (key == settings_key_) return;
  settings_key_ = key;
  for (auto& [name, e] : cache_) {
    e.raw_whole.reset();
    e.raw_info.reset();
    e.raw_part.reset();
    e.raw_error.clear();
  }
}

ComputedFrame SequenceContext::compute(const FrameRequest& request, const ReadOptions& read, GBuffer&& frame,
                                       std::vector<std::string>& notes) {
  if (request.temporal_per_side <= 0 || request.neighbours.empty()) return compute_frame(std::move(frame), request);
  Entry& self = cache_[sequence_name(request)];
  if (!self.camera_has_world) {
    notes.push_back("temporal: none (the frame's camera has no world transform to relate others to)");
    return compute_frame(std::move(frame), request);
  }
  RawFrame raw;
  const std::string key = store_ ? raw_terms_key(request, request.input_path, request.read.camera_json) : "";
  if (self.raw_whole) {
    raw = std::move(*self.raw_whole);
    self.raw_whole.reset();
    self.raw_info.reset();
  } else if (std::optional<TermOutputs> kept = store_ ? store_->take_terms(key) : std::nullopt) {
    raw = with_raw_terms(std::move(frame), std::move(*kept), request);
    ++reads_.raw_kept;
  } else {
    raw = compute_raw_frame(std::move(frame), request);
    ++reads_.raw_terms;
  }
  self.raw_part = std::make_shared<const RawFrame>(temporal_part(raw));
  if (store_) store_->put(key, self.raw_part);
  std::vector<const RawFrame*> neighbours;
  std::vector<std::string> names;
  for (const NeighbourFrame& n : within_places(request.neighbours, request.temporal_per_side)) {
    const Entry& e = neighbour_raw(request, read, n);
    if (e.raw_part) {
      neighbours.push_back(e.raw_part.get());
      names.push_back(file_name(n.path));
    } else {
      notes.push_back(file_name(n.path) + ": not used for temporal filtering (" + e.raw_error + ")");
    }
  }
  ComputedFrame out = finish_frame(std::move(raw), neighbours, request);
  drop_raw_outside(request);
  if (store_) store_->keep(size_t(2 * request.temporal_per_side + 1));
  add_temporal_notes(out, names, notes);
  return out;
}

void SequenceContext::add_temporal_notes(const ComputedFrame& out, const std::vector<std::string>& names,
                                         std::vector<std::string>& notes) const {
  std::string used;
  for (size_t i = 0; i < out.temporal.size(); ++i)
    if (out.temporal[i].used) used += " " + names[i];
  const std::string kept = reads_.raw_kept > 0 ? ", " + std::to_string(reads_.raw_kept) + " kept from earlier frames"
                                                : std::string();
  notes.push_back("temporal:" + (used.empty() ? std::string(" none") : used) + " (raw terms computed " +
                  counted(reads_.raw_terms, "time") + " for " + counted(reads_.frames, "frame") + kept + ")");
  for (size_t i = 0; i < out.temporal.size(); ++i) {
    const TemporalUse& u = out.temporal[i];
    if (u.used && u.changed_px > 0)
      notes.push_back(names[i] + ": the surroundings of " + std::to_string(u.changed_px) +
                      " pixels changed in it (something moved): they do not take its terms");
    if (u.used) continue;
    const std::string why = u.overlap <= 0.0f ? std::string("it sees none of this frame's surfaces")
                                              : "another surface at " + std::to_string(int(100.0f * u.disagreement)) +
                                                    "% of this frame's surfaces it sees: a cut?";
    notes.push_back(names[i] + ": not used for temporal filtering (" + why + ")");
  }
}

const SequenceContext::Entry& SequenceContext::neighbour_raw(const FrameRequest& request, const ReadOptions& read,
                                                             const NeighbourFrame& n) {
  // std::map: the reference stays valid; read_in_window below keeps the cache, as the
  // neighbour's read differs from the frame's only in its sidecar, which is not in read_key.
  Entry& e = cache_[n.path];
  if (e.raw_part || !e.raw_error.empty()) return e;
  // The neighbour as its own job computes it: its own views among its own candidates.
  FrameRequest r = request;
  r.input_path = n.open_path.empty() ? n.path : n.open_path;
  r.input_name = n.path;
  r.output_path.clear();
  const NeighbourFrame self{sequence_name(request), 0, false,
                            request.input_name.empty() ? std::string() : request.input_path, request.read.camera_json};
  r.neighbours = neighbours_of_neighbour(self, request.neighbours, n, view_candidate_places(request.views_per_side));
  const std::string key = store_ ? raw_terms_key(r, r.input_path, n.camera_json) : "";
  if (std::shared_ptr<const RawFrame> kept = store_ ? store_->part(key) : nullptr) {
    ++reads_.raw_kept;
    e.raw_part = std::move(kept);
    return e;
  }
  if (e.unreadable) {  // not read again
    e.raw_error = e.error;
    return e;
  }
  ReadResult f = read_in_window(r, neighbour_read(n, read));
  if (!f.ok()) {
    e.raw_error = f.error;
    remember_failed_read(n, std::move(f), e);
    return e;
  }
  if (!has_world(f.info)) e.raw_error = "no camera with a world transform";
  if (!e.raw_error.empty() || !resolve_frame_radius(r, f.info, e.raw_error)) return e;
  RawFrame raw = compute_raw_frame(std::move(f.gbuffer), r);
  ++reads_.raw_terms;
  e.raw_part = std::make_shared<const RawFrame>(temporal_part(raw));
  // A frame after this one may come as a request of its own: its raw terms are kept whole.
  if (store_) store_->put(key, e.raw_part, n.frame_offset > 0 ? std::optional<TermOutputs>(raw.raw) : std::nullopt);
  if (n.computed_later) {
    e.raw_whole = std::make_shared<RawFrame>(std::move(raw));
    e.raw_info = std::move(f.info);
  }
  return e;
}

SequenceContext::Entry& SequenceContext::candidate(const NeighbourFrame& n, const ReadOptions& read) {
  Entry& e = cache_[n.path];
  if (e.camera || !e.error.empty()) return e;
  const ReadResult header = inspect_gbuffer(n.open_path.empty() ? n.path : n.open_path, neighbour_read(n, read));
  ++reads_.headers;
  if (!header.ok()) {
    e.error = header.error;
    e.unreadable = header.exhausted == ResourceFailure::none;
    return e;
  }
  e.camera = header.gbuffer.camera;
  e.camera_has_world = has_world(header.info);
  return e;
}

bool SequenceContext::load_view(const NeighbourFrame& n, const ReadOptions& read, const ReadOptions& view_read,
                                Entry& e) {
  // A view read for its depth only is read again for a request that also needs its light.
  const ReadOptions as_view = neighbour_read(n, view_read);
  if (e.view && e.view_read == read_key(as_view)) return true;
  if (e.unreadable) return false;  // not read again
  const std::string& path = n.open_path.empty() ? n.path : n.open_path;
  ReadResult r = n.computed_later ? read_frame(path, neighbour_read(n, read)) : read_gbuffer(path, as_view);
  ++(n.computed_later ? reads_.whole : reads_.depth_only);
  if (!r.ok()) {
    e.error = r.error;
    remember_failed_read(n, std::move(r), e);
    return false;
  }
  e.view = DepthView{r.gbuffer.camera, r.gbuffer.depth_view, file_name(n.path)};
  if (as_view.read_albedo) e.view->albedo = r.gbuffer.albedo;
  if (as_view.read_lighting) e.view->lighting = r.gbuffer.lighting;
  e.view_read = read_key(as_view);
  if (n.computed_later) e.whole = std::move(r);
  return true;
}

void SequenceContext::remember_failed_read(const NeighbourFrame& n, ReadResult&& failed, Entry& e) {
  // Memory or threads running out say nothing of the file: it may read another time.
  if (failed.exhausted != ResourceFailure::none) return;
  e.unreadable = true;
  e.error = failed.error;
  // Its own turn in this worker fails with this read's error instead of reading it again.
  if (n.computed_later) e.whole = std::move(failed);
}

void SequenceContext::attach_views(const FrameRequest& request, const ReadOptions& read, ReadResult& frame) {
  FrameInfo& info = frame.info;
  const std::vector<NeighbourFrame> within =
      within_places(request.neighbours, view_candidate_places(request.views_per_side));
  const GBuffer& g = frame.gbuffer;
  ViewSelectionSettings settings;
  settings.views_per_side = request.views_per_side;
  const float scene_depth_world = median_foreground_depth(g.depth_view, g.mask);
  const ReadOptions view_read = view_reads_for(request, read, !g.lighting.empty());
  // A chosen view whose header read but whose pixels do not is left out of the candidates
  // and the choice made again, so that the next one on its side takes its place.
  std::set<std::string> unreadable;
  for (bool first = true;; first = false) {
    std::vector<ViewCandidate> candidates;
    std::vector<const NeighbourFrame*> sources;
    for (const NeighbourFrame& n : within) {
      if (unreadable.count(n.path)) continue;
      Entry& e = candidate(n, read);
      if (!e.camera) {
        if (first) info.notes.push_back(file_name(n.path) + ": skipped as a view (" + e.error + ")");
        continue;
      }
      candidates.push_back({file_name(n.path), n.frame_offset, e.camera_has_world, e.camera->width_px,
                            e.camera->height_px, e.camera->view_to_world});
      sources.push_back(&n);
    }
    const ViewChoice choice = select_views(g.camera.view_to_world, g.width_px(), g.height_px(), scene_depth_world,
                                           candidates, settings);
    std::vector<const DepthView*> views;
    for (size_t i : choice.chosen) {
      Entry& e = cache_[sources[i]->path];
      if (load_view(*sources[i], read, view_read, e)) {
        views.push_back(&*e.view);
        continue;
      }
      info.notes.push_back(candidates[i].name + ": skipped as a view (" + e.error + ")");
      unreadable.insert(sources[i]->path);
    }
    if (views.size() < choice.chosen.size()) continue;  // at most once per candidate
    info.notes.insert(info.notes.end(), choice.notes.begin(), choice.notes.end());
    std::string names;
    for (const DepthView* v : views) {
      frame.gbuffer.views.push_back(*v);
      names += " " + v->name;
    }
    info.notes.push_back("views:" + (names.empty() ? std::string(" none") : names) + " (read " +
                         counted(reads_.whole + reads_.depth_only, "file") + " for " + counted(reads_.frames, "frame") +
                         ": " + std::to_string(reads_.whole) + " whole, " + std::to_string(reads_.depth_only) +
                         " as views only; " + counted(reads_.headers, "header") + ")");
    return;
  }
}

void SequenceContext::drop_raw_outside(const FrameRequest& request) {
  std::set<std::string> window{sequence_name(request)};
  for (const NeighbourFrame& n : within_places(request.neighbours, request.temporal_per_side)) window.insert(n.path);
  for (auto& [name, e] : cache_)
    if (!window.count(name)) e.raw_part.reset();
}

std::string SequenceContext::raw_terms_key(const FrameRequest& frame, const std::string& path,
                                           const std::string& camera_json) const {
  std::vector<std::string> candidates;
  if (frame.views_per_side > 0)
    for (const NeighbourFrame& n : within_places(frame.neighbours, view_candidate_places(frame.views_per_side)))
      candidates.push_back(n.path + "=" + frame_version_key(n.open_path.empty() ? n.path : n.open_path, n.camera_json));
  std::sort(candidates.begin(), candidates.end());  // a set: each request lists them in its own order
  std::string key = settings_key_ + "\n" + sequence_name(frame) + "=" + frame_version_key(path, camera_json);
  for (const std::string& c : candidates) key += "\n" + c;
  return key;
}

void SequenceContext::keep_window(const FrameRequest& request) {
  std::set<std::string> window{sequence_name(request)};
  for (const NeighbourFrame& n : request.neighbours) window.insert(n.path);
  for (auto it = cache_.begin(); it != cache_.end();) it = window.count(it->first) ? std::next(it) : cache_.erase(it);
}

std::list<RawTermsStore::Item>::iterator RawTermsStore::find(const std::string& key) {
  const auto it = std::find_if(items_.begin(), items_.end(), [&](const Item& i) { return i.key == key; });
  if (it != items_.end()) items_.splice(items_.begin(), items_, it);
  return it;
}

std::shared_ptr<const RawFrame> RawTermsStore::part(const std::string& key) {
  const auto it = find(key);
  return it == items_.end() ? nullptr : it->part;
}

std::optional<TermOutputs> RawTermsStore::take_terms(const std::string& key) {
  const auto it = find(key);
  if (it == items_.end() || !it->terms) return std::nullopt;
  std::optional<TermOutputs> terms = std::move(it->terms);
  it->terms.reset();
  return terms;
}

void RawTermsStore::put(const std::string& key, std::shared_ptr<const RawFrame> part,
                        std::optional<TermOutputs> terms) {
  if (const auto it = find(key); it != items_.end()) items_.erase(it);
  items_.push_front({key, std::move(part), std::move(terms)});
}

void RawTermsStore::keep(size_t count) {
  while (items_.size() > count) items_.pop_back();
}

}  // namespace ssdo
