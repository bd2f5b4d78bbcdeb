// A worker's sequence context: the frames of a shot it has read, so that each file is read
// once per batch while its frames use their neighbours as extra views (GBuffer::views).
//
// For a frame with views_per_side > 0 and neighbours, read():
// 1. reads the frame whole (or takes it whole from the cache when an earlier frame read it
//    as a view), and keeps its depth and camera as a view for the frames after it;
// 2. learns the candidates' cameras from their headers (inspect_gbuffer: the header and
//    the sidecar, no pixels) and chooses the views by parallax at the frame's median
//    depth (service/view_selection.h);
// 3. reads each chosen view not in the cache: whole when the same worker computes it
//    later (NeighbourFrame::computed_later: it is then read once for both uses), else its
//    depth only, with its albedo and lighting when the frame computes SSDO
//    (view_reads_for, service/pipeline.h);
// 4. drops what no frame of the current window needs (a sliding window: frames are
//    computed in order within a worker).
// Memory: at most one depth map and camera per frame of the window (2 x 3K + 1) and the
// whole frames of the views ahead (at most K). A neighbour that cannot be used (unreadable,
// no camera, another size, beyond a cut) is a note in the frame's info, never an error.
// With views_per_side 0 the frame is read exactly as read_frame does, and nothing is kept.
//
// With temporal filtering (temporal_per_side K > 0), compute() finishes the frame over the raw
// terms of the K frames on each side (kernels/temporal.h). Each neighbour's raw terms are
// computed once per worker, as the neighbour's own job would compute them (its own views,
// chosen among its own candidates: the frame's neighbour list spans them, neighbour_places),
// and kept while the window needs them: whole for a frame this worker computes later (its
// own turn then only finishes it), else only what the filter reads (temporal_part). A
// neighbour outside the batch's frames (a farm chunk's edge) is computed and not written.
// Memory: at most 2K + 1 frames of raw terms and guides, K of them whole.
#pragma once

#include <list>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "service/pipeline.h"

namespace ssdo {

// Raw terms kept across a worker's requests, for the watch and socket modes, whose requests
// each read through a context of their own (their files are opened per request,
// service/job_files.h). An entry is keyed by the settings and by the versions of every file
// its raw terms were computed from (the frame, its camera file, the frames it chose its views
// among: raw_terms_key), so a frame rewritten between requests is computed again and never
// lent stale. What is kept: what the temporal filter reads of the frame (temporal_part), and
// for a frame after the one that computed it (which may still come as a request of its own)
// its whole raw terms, so that its own turn reads its G-buffer again but does not compute them.
class RawTermsStore {
 public:
  // The frame kept under `key` (temporal_part's images), or null.
  std::shared_ptr<const RawFrame> part(const std::string& key);
  // The whole raw terms kept under `key`, handed over (kept no more), or nullopt.
  std::optional<TermOutputs> take_terms(const std::string& key);
  void put(const std::string& key, std::shared_ptr<const RawFrame> part, std::optional<TermOutputs> terms = {});
  // Keeps the `count` entries used last (a request's window: 2K + 1).
  void keep(size_t count);
  void clear() { items_.clear(); }

 private:
  struct Item {
    std::string key;
    std::shared_ptr<const RawFrame> part;
    std::optional<TermOutputs> terms;
  };
  std::list<Item>::iterator find(const std::string& key);  // moved to the front when found
  std::list<Item> items_;  // used last first
};

class SequenceContext : public FrameSource {
 public:
  // Raw terms are also looked up in, and kept in, `store` (which outlives this context).
  void share_raw_terms(RawTermsStore* store) { store_ = store; }

  ReadResult read(const FrameRequest& request, const ReadOptions& read) override;
  ComputedFrame compute(const FrameRequest& request, const ReadOptions& read, GBuffer&& frame,
                        std::vector<std::string>& notes) override;

  // Forgets every frame kept (views, whole frames, raw terms, also in the shared store): the
  // memory they hold goes back to the worker's heap.
  void clear();

  // Identifies the settings the raw terms of the next requests are computed with (e.g. their
  // options as JSON): raw terms computed with other settings are dropped. Requests of one
  // batch share one.
  void use_settings(const std::string& key);

  // Files read since the worker started: frames read whole, views read depth-only, and
  // headers inspected for a candidate's camera.
  struct Reads {
    long whole = 0, depth_only = 0, headers = 0, frames = 0;
    long raw_terms = 0;  // frames whose raw terms were computed (temporal filtering)
    long raw_kept = 0;   // frames whose raw terms came from the store (share_raw_terms)
  };
  const Reads& reads() const { return reads_; }

 private:
  struct Entry {
    std::optional<ReadResult> whole;   // read whole for a frame computed later
    std::optional<DepthView> view;     // its depth and camera (and light: view_read)
    std::string view_read;             // read_key of the read that gave `view`
    std::optional<Camera> camera;      // from its header
    bool camera_has_world = false;
    std::string error;                 // why it cannot be a view
    // A read of the file (its header, or its pixels) failed, not for want of memory: it is
    // not read again in this batch, as a view or a temporal neighbour.
    bool unreadable = false;
    // Temporal filtering: the raw frame whole (a frame this worker computes later) and what
    // the filter reads of it; raw_error: why its raw terms could not be computed.
    std::shared_ptr<RawFrame> raw_whole;
    std::optional<FrameInfo> raw_info;  // raw_whole's frame as read
    std::shared_ptr<const RawFrame> raw_part;
    std::string raw_error;
  };
  Entry& candidate(const NeighbourFrame& n, const ReadOptions& read);
  bool load_view(const NeighbourFrame& n, const ReadOptions& read, const ReadOptions& view_read, Entry& e);
  // A neighbour's whole read that failed: the file is not read again in this batch, as a
  // view or a temporal neighbour (Entry::error), nor for its own turn when this worker
  // computes it later (Entry::whole keeps the failure).
  void remember_failed_read(const NeighbourFrame& n, ReadResult&& failed, Entry& e);
  void attach_views(const FrameRequest& request, const ReadOptions& read, ReadResult& frame);
  ReadResult read_in_window(const FrameRequest& request, const ReadOptions& read);
  // A temporal neighbour's cache entry with its raw terms (raw_part), computed or kept, or
  // why there are none (raw_error).
  const Entry& neighbour_raw(const FrameRequest& request, const ReadOptions& read, const NeighbourFrame& n);
  void keep_window(const FrameRequest& request);
  // The -v notes of a temporally filtered frame: the neighbours used, the raw-term count,
  // and why each unused one was left out.
  void add_temporal_notes(const ComputedFrame& out, const std::vector<std::string>& names,
                          std::vector<std::string>& notes) const;
  // Releases the raw terms of the frames beyond the request's temporal window (frames are
  // computed in order: no later frame of the worker reads them).
  void drop_raw_outside(const FrameRequest& request);
  // The key of a frame's raw terms in the store (RawTermsStore): the settings, and the
  // versions of the frame (opened as `path`, its camera file `camera_json`) and of the
  // frames its views are chosen among.
  std::string raw_terms_key(const FrameRequest& frame, const std::string& path, const std::string& camera_json) const;

  std::map<std::string, Entry> cache_;
  std::string read_key_;  // the read options the whole frames were read with
  std::string settings_key_;  // use_settings
  Reads reads_;
  RawTermsStore* store_ = nullptr;
};

// The foreground's median planar depth (every 4th pixel of every 4th row): the scene depth
// parallax is measured at. 0 without foreground.
float median_foreground_depth(const cv::Mat& depth_view, const cv::Mat& mask);

}  // namespace ssdo
