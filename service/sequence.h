// A shot's frames as a sequence: which files are frames of one shot, their order, and the
// neighbours each frame may use as extra views (service/view_selection.h chooses among
// them, service/sequence_context.h reads them).
//
// Files of one folder whose names differ only in their frame number are frames of one
// sequence, ordered by that number: shot.0001.exr, shot.0002.exr; orbit_f0.exr,
// orbit_f1.exr; shot.0001.v2.exr, shot.0002.v2.exr; a pattern's expansion (shot.####.exr
// with --frames) is the same. The frame number is the last run of digits between
// separators (not the "2" of "v2"), else the last run of digits; a '-' right after a
// separator makes it negative ("shot.-003"). A name without digits is a frame alone.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace ssdo {

// A frame another frame may use as an extra view.
struct NeighbourFrame {
  std::string path;             // its name: its identity in the sequence
  int frame_offset = 0;         // its place minus the frame's (never 0): frame numbers over the sequence's step
  bool computed_later = false;  // the same worker computes it later: read it whole, once
  std::string open_path;        // what to read: an opened descriptor's name, or empty = path
  std::string camera_json;      // its camera file when opened for it, else empty = beside it
};

struct SequencePlace {
  std::string sequence;  // folder / name with the frame number taken out
  long number = 0;       // the frame number
};

// The place of `path` in its sequence; nullopt for a name without a frame number.
std::optional<SequencePlace> sequence_place(const std::string& path);

// For each of `frames`, the other frames of its sequence among `frames` within
// `window` places before and after it, nearest first per side. A place is a frame number
// over the sequence's step (the greatest common divisor of its numbers' differences: 2 for
// a shot rendered on twos), so a frame missing from `frames` still counts as one: a
// folder with a failed frame gives each frame the neighbours a pattern over the whole
// range gives it. Of two files with one frame number the first in `frames` order is the
// frame. Frames that are not part of a sequence get none; window 0 gives none.
std::vector<std::vector<NeighbourFrame>> sequence_neighbours(const std::vector<std::string>& frames, int window);

// How many places on each side of a frame its neighbour list spans: the candidates of its
// views (view_candidate_places) and, with temporal filtering, the temporal neighbours and
// the candidates of their own views (a neighbour's raw terms are computed with its views).
int neighbour_places(int views_per_side, int temporal_per_side);
// The places on each side among which a frame's views are chosen (service/view_selection.h).
int view_candidate_places(int views_per_side);

// The entries of `neighbours` (one frame's list, as sequence_neighbours gives it) within
// `places` places of the frame (|frame_offset| <= places), in the list's order.
std::vector<NeighbourFrame> within_places(const std::vector<NeighbourFrame>& neighbours, int places);

// The neighbour list neighbour `of` of a frame would get from sequence_neighbours with
// `places`, derived from the frame's own list (`self`: the frame as a neighbour, its
// frame_offset 0): the frames of the list and the frame itself within `places` places of
// `of`, offsets relative to `of`, nearest first per side. Complete when the frame's list
// spans `places` places beyond `of` on each side (neighbour_places).
std::vector<NeighbourFrame> neighbours_of_neighbour(const NeighbourFrame& self,
                                                    const std::vector<NeighbourFrame>& neighbours,
                                                    const NeighbourFrame& of, int places);

// The frames of `path`'s sequence in its folder (frame files, service/frame_list.h) within
// `window` places of it: the neighbours of a frame that arrives in a watched folder.
std::vector<NeighbourFrame> folder_neighbours(const std::string& path, int window);

// Whether `output` is at least as new as every neighbour in `neighbours` and its sidecar (a
// neighbour re-rendered since changes the frame's views and temporal terms). A neighbour
// that does not exist changes nothing (window_attribute tells when one appears or goes).
bool neighbours_older_than(const std::vector<NeighbourFrame>& neighbours, const std::string& output);

// The kWindowAttribute value (request_options.h) of an output computed with `views` and
// `temporal` neighbours per side from `neighbours` (its frame's list): the window and the
// file names of the frames in it that exist, sorted; one JSON object. The worker writes it
// with the window it used, process and the watch compare it with the window they would use.
std::string window_attribute(const std::vector<NeighbourFrame>& neighbours, int views, int temporal);

// One camera file for every neighbour (a --camera given for the whole run: a locked-off shot's
// one camera): each neighbour is read with `camera_json` instead of the sidecar beside it, as
// the frame itself is. Nothing when `camera_json` is empty.
void give_neighbours_camera(std::vector<NeighbourFrame>& neighbours, const std::string& camera_json);

// The neighbours of a frame named explicitly (a socket request's "views"): offsets from
// the frame numbers when they share the frame's sequence, else 1, 2, ... in the given order.
// The frame itself and repeated names are left out (paths as resolved: one spelling each).
std::vector<NeighbourFrame> named_neighbours(const std::string& path, const std::vector<std::string>& views);

}  // namespace ssdo
