#include "service/sequence.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <map>

#include "service/frame_list.h"

namespace ssdo {

namespace fs = std::filesystem;

namespace {

// Frame numbers beyond this many digits are not frame numbers (a date, a hash).
constexpr size_t kMaxFrameDigits = 9;

}  // namespace

std::optional<SequencePlace> sequence_place(const std::string& path) {
  const fs::path p(path);
  const std::string stem = p.stem().string();
  size_t end = stem.size();
  while (end > 0 && !std::isdigit(static_cast<unsigned char>(stem[end - 1]))) --end;
  size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
  if (begin == end || end - begin > kMaxFrameDigits) return std::nullopt;
  // A minus sign before the digits is a separator ("shot-0001"), not a negative frame.
  SequencePlace place;
  place.number = std::strtol(stem.substr(begin, end - begin).c_str(), nullptr, 10);
  place.sequence = (p.parent_path() / (stem.substr(0, begin) + "#" + stem.substr(end) + p.extension().string()))
                       .lexically_normal()
                       .string();
  return place;
}

std::vector<std::vector<NeighbourFrame>> sequence_neighbours(const std::vector<std::string>& frames, int window) {
  std::vector<std::vector<NeighbourFrame>> out(frames.size());
  if (window <= 0) return out;
  // Each sequence's frames in frame-number order, as (number, index into frames).
  std::map<std::string, std::vector<std::pair<long, size_t>>> sequences;
  for (size_t i = 0; i < frames.size(); ++i)
    if (const auto place = sequence_place(frames[i])) sequences[place->sequence].push_back({place->number, i});
  for (auto& [name, members] : sequences) {
    std::stable_sort(members.begin(), members.end());
    const long n = long(members.size());
    for (long k = 0; k < n; ++k) {
      std::vector<NeighbourFrame>& list = out[members[k].second];
      for (long d = 1; d <= window; ++d)
        for (const long j : {k - d, k + d})
          if (j >= 0 && j < n && members[j].first != members[k].first)
            list.push_back({frames[members[j].second], int(members[j].first - members[k].first), false, {}, {}});
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
  for (size_t i = 0; i < views.size(); ++i) {
    const auto other = sequence_place(views[i]);
    const bool same = place && other && other->sequence == place->sequence && other->number != place->number;
    out.push_back({views[i], same ? int(other->number - place->number) : int(i + 1), false, {}, {}});
  }
  return out;
}

}  // namespace ssdo
