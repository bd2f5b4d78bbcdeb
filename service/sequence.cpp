#include "service/sequence.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <numeric>

#include <nlohmann/json.hpp>

#include "service/frame_list.h"
#include "service/view_selection.h"

namespace ssdo {

namespace fs = std::filesystem;

namespace {

// Frame numbers beyond this many digits are not frame numbers (a date, a hash).
constexpr size_t kMaxFrameDigits = 9;

}  // namespace

std::optional<SequencePlace> sequence_place(const std::string& path) {
  const fs::path p(path);
  const std::string stem = p.stem().string();
  auto digit = [&](size_t i) { return std::isdigit(static_cast<unsigned char>(stem[i])) != 0; };
  auto word = [&](size_t i) { return std::isalnum(static_cast<unsigned char>(stem[i])) != 0; };
  // The frame number: the last run of digits that stands alone between separators
  // ("shot.0001.v2": 0001, not the 2 of a version tag "v2"; "take2_0001": 0001), else the
  // last run of digits ("orbit_f3", "frame0001").
  size_t begin = 0, end = 0, last_begin = 0, last_end = 0;
  for (size_t i = 0; i < stem.size();) {
    if (!digit(i)) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j < stem.size() && digit(j)) ++j;
    last_begin = i, last_end = j;
    if ((i == 0 || !word(i - 1)) && (j == stem.size() || !word(j))) begin = i, end = j;
    i = j;
  }
  if (end == 0) begin = last_begin, end = last_end;
  if (begin == end || end - begin > kMaxFrameDigits) return std::nullopt;
  SequencePlace place;
  place.number = std::strtol(stem.substr(begin, end - begin).c_str(), nullptr, 10);
  // A minus sign right after a separator is the number's ("shot.-003", as a pattern writes
  // frame -3); after a word it is a separator ("shot-0001").
  if (begin > 0 && stem[begin - 1] == '-' && (begin == 1 || !word(begin - 2))) {
    --begin;
    place.number = -place.number;
  }
  place.sequence = (p.parent_path() / (stem.substr(0, begin) + "#" + stem.substr(end) + p.extension().string()))
                       .lexically_normal()
                       .string();
  return place;
}

namespace {

// A sequence's place step: the greatest common divisor of the differences between its
// frame numbers (1 for a shot with every frame; 2 for one rendered on twos), so that a
// place is a frame of the sequence whether or not its file is there: a missing frame in
// the middle (a failed render) is a place, as it is in a pattern's list of frames.
long place_step(const std::vector<std::pair<long, size_t>>& members) {
  long step = 0;
  for (size_t k = 1; k < members.size(); ++k) step = std::gcd(step, members[k].first - members[k - 1].first);
  return step > 0 ? step : 1;
}

}  // namespace

std::vector<std::vector<NeighbourFrame>> sequence_neighbours(const std::vector<std::string>& frames, int window) {
  std::vector<std::vector<NeighbourFrame>> out(frames.size());
  if (window <= 0) return out;
  // Each sequence's frames in frame-number order, as (number, index into frames).
  std::map<std::string, std::vector<std::pair<long, size_t>>> sequences;
  for (size_t i = 0; i < frames.size(); ++i)
    if (const auto place = sequence_place(frames[i])) sequences[place->sequence].push_back({place->number, i});
  for (auto& [name, members] : sequences) {
    std::stable_sort(members.begin(), members.end());
    const long step = place_step(members);
    // Place p of the sequence: its first file of that frame number (a second file of the
    // same number, "shot.1" beside "shot.0001", is no other frame).
    std::map<long, size_t> by_place;
    const long first = members.front().first;  // every number is first + a multiple of step
    for (const auto& [number, index] : members) by_place.emplace((number - first) / step, index);
    for (const auto& [number, index] : members) {
      std::vector<NeighbourFrame>& list = out[index];
      const long place = (number - first) / step;
      for (long d = 1; d <= window; ++d)
        for (const long p : {place - d, place + d})
          if (const auto it = by_place.find(p); it != by_place.end())
            list.push_back({frames[it->second], int(p - place), false, {}, {}});
    }
  }
  return out;
}

std::vector<NeighbourFrame> folder_neighbours(const std::string& path, int window) {
  const auto place = sequence_place(path);
  if (!place || window <= 0) return {};
  std::vector<std::string> frames;
  std::error_code ec;
  const fs::path folder = fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
  for (const fs::directory_entry& e : fs::directory_iterator(folder, ec)) {
    const std::string f = (fs::path(path).parent_path() / e.path().filename()).string();
    if (!e.is_regular_file(ec) || !is_frame_file(f)) continue;
    const auto other = sequence_place(f);
    if (f == path || (other && other->sequence == place->sequence)) frames.push_back(f);
  }
  std::sort(frames.begin(), frames.end());
  const auto at = std::find(frames.begin(), frames.end(), path);
  if (at == frames.end()) return {};
  return sequence_neighbours(frames, window)[size_t(at - frames.begin())];
}

std::vector<NeighbourFrame> named_neighbours(const std::string& path, const std::vector<std::string>& views) {
  const auto place = sequence_place(path);
  std::vector<NeighbourFrame> out;
  for (const std::string& view : views) {
    // The frame itself, or a view named twice, would count as views that agree with it.
    const bool named_before =
        std::any_of(out.begin(), out.end(), [&](const NeighbourFrame& n) { return n.path == view; });
    if (view == path || named_before) continue;
    const auto other = sequence_place(view);
    const bool same = place && other && other->sequence == place->sequence && other->number != place->number;
    out.push_back({view, same ? int(other->number - place->number) : int(out.size() + 1), false, {}, {}});
  }
  // In sequence_neighbours' order (nearest first, the earlier frame first), whatever order
  // the request named them in: the temporal filter sums the neighbours in list order, so a
  // request and the batch give the same bits.
  std::stable_sort(out.begin(), out.end(), [](const NeighbourFrame& a, const NeighbourFrame& b) {
    return std::make_pair(std::abs(a.frame_offset), a.frame_offset) <
           std::make_pair(std::abs(b.frame_offset), b.frame_offset);
  });
  return out;
}

int view_candidate_places(int views_per_side) { return kCandidateFramesPerView * std::max(0, views_per_side); }

int neighbour_places(int views_per_side, int temporal_per_side) {
  return view_candidate_places(views_per_side) + std::max(0, temporal_per_side);
}

std::vector<NeighbourFrame> within_places(const std::vector<NeighbourFrame>& neighbours, int places) {
  std::vector<NeighbourFrame> out;
  for (const NeighbourFrame& n : neighbours)
    if (std::abs(n.frame_offset) <= places) out.push_back(n);
  return out;
}

std::vector<NeighbourFrame> neighbours_of_neighbour(const NeighbourFrame& self,
                                                    const std::vector<NeighbourFrame>& neighbours,
                                                    const NeighbourFrame& of, int places) {
  std::vector<const NeighbourFrame*> all{&self};
  bool found = false;
  for (const NeighbourFrame& n : neighbours) {
    all.push_back(&n);
    found |= n.frame_offset == of.frame_offset;
  }
  if (!found) return {};
  // Nearest first per side, as sequence_neighbours orders a list.
  std::vector<NeighbourFrame> out;
  for (long d = 1; d <= places; ++d)
    for (const long p : {of.frame_offset - d, of.frame_offset + d})
      for (const NeighbourFrame* n : all)
        if (n->frame_offset == p) {
          NeighbourFrame f = *n;
          f.frame_offset = int(p - of.frame_offset);
          out.push_back(f);
          break;
        }
  return out;
}

bool neighbours_older_than(const std::vector<NeighbourFrame>& neighbours, const std::string& output) {
  return std::all_of(neighbours.begin(), neighbours.end(), [&](const NeighbourFrame& n) {
    std::error_code ec;
    return !fs::exists(n.path, ec) || output_up_to_date_with_sidecar(n.path, output);
  });
}

std::string window_attribute(const std::vector<NeighbourFrame>& neighbours, int views, int temporal) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const NeighbourFrame& n : within_places(neighbours, neighbour_places(views, temporal)))
    if (fs::exists(n.path, ec)) names.push_back(fs::path(n.path).filename().string());
  std::sort(names.begin(), names.end());
  return nlohmann::json{{"views", views}, {"temporal", temporal}, {"frames", names}}.dump();
}

void give_neighbours_camera(std::vector<NeighbourFrame>& neighbours, const std::string& camera_json) {
  if (camera_json.empty()) return;
  for (NeighbourFrame& n : neighbours) n.camera_json = camera_json;
}

}  // namespace ssdo
