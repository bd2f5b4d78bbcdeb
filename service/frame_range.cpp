#include "service/frame_range.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <sstream>

namespace ssdo {

namespace {

// Parses an optionally signed integer filling all of `s`.
bool parse_int(const std::string& s, int& value) {
  if (s.empty()) return false;
  const char* first = s.data();
  const char* last = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(first, last, value);
  return ec == std::errc() && ptr == last;
}

struct Pattern {
  size_t pos = std::string::npos, length = 0;
  int digits = 0;
};

Pattern find_pattern(const std::string& path) {
  // The pattern is searched in the file name only: folders may contain '#' or '@'.
  const size_t name_start = path.find_last_of('/') == std::string::npos ? 0 : path.find_last_of('/') + 1;
  for (size_t i = name_start; i < path.size(); ++i) {
    const char c = path[i];
    if (c == '#' || c == '@') {
      size_t j = i;
      while (j < path.size() && path[j] == c) ++j;
      const int run = int(j - i);
      return {i, size_t(run), (c == '#' && run == 1) ? 4 : run};
    }
    if (c == '%') {
      // %d or %0Nd
      size_t j = i + 1;
      int width = 0;
      if (j < path.size() && path[j] == '0') {
        ++j;
        while (j < path.size() && std::isdigit(static_cast<unsigned char>(path[j])) && width < 100)
          width = width * 10 + (path[j++] - '0');
      }
      if (j < path.size() && path[j] == 'd') return {i, j + 1 - i, width};
    }
  }
  return {};
}

}  // namespace

bool parse_frame_ranges(const std::string& spec, std::vector<int>& frames, std::string& error,
                        size_t max_frames) {
  if (spec.empty()) {
    error = "empty frame range";
    return false;
  }
  std::stringstream ss(spec);
  std::string part;
  while (std::getline(ss, part, ',')) {
    if (part.empty()) {
      error = "frame range '" + spec + "': empty item between commas";
      return false;
    }
    int step = 1;
    std::string range = part;
    if (const size_t x = part.find('x'); x != std::string::npos) {
      if (!parse_int(part.substr(x + 1), step) || step <= 0) {
        error = "frame range item '" + part + "': the step after 'x' must be a positive integer";
        return false;
      }
      range = part.substr(0, x);
    }
    // "A-B": the dash separating A and B is the first '-' after the first character
    // (so "-5--1" reads as -5 to -1).
    int first = 0, last = 0;
    const size_t dash = range.find('-', 1);
    if (dash == std::string::npos) {
      if (!parse_int(range, first)) {
        error = "frame range item '" + part + "': expected N, A-B or A-BxSTEP";
        return false;
      }
      last = first;
    } else if (!parse_int(range.substr(0, dash), first) || !parse_int(range.substr(dash + 1), last)) {
      error = "frame range item '" + part + "': expected N, A-B or A-BxSTEP";
      return false;
    }
    const long long span = (static_cast<long long>(last) - first);
    const long long count = (span >= 0 ? span : -span) / step + 1;
    if (frames.size() + size_t(count) > max_frames) {
      error = "frame range '" + spec + "' has more than " + std::to_string(max_frames) + " frames";
      return false;
    }
    const int dir = last >= first ? 1 : -1;
    for (long long k = 0; k < count; ++k) frames.push_back(int(first + dir * k * step));
  }
  return true;
}

std::string format_frame_ranges(const std::vector<int>& frames) {
  std::string out;
  for (size_t i = 0; i < frames.size();) {
    if (!out.empty()) out += ',';
    const long long first = frames[i];
    const long long step = i + 1 < frames.size() ? frames[i + 1] - first : 0;
    size_t j = i + 1;  // one past the run [i, j) with a constant, non-zero step
    while (step != 0 && j < frames.size() && frames[j] - (long long)frames[j - 1] == step) ++j;
    // A run of two is worth a range only with step 1 ("4-5" rather than "4,5").
    const bool range = j - i >= 3 || (j - i == 2 && (step == 1 || step == -1));
    if (!range) {
      out += std::to_string(first);
      ++i;
      continue;
    }
    out += std::to_string(first) + '-' + std::to_string(frames[j - 1]);
    if (step != 1 && step != -1) out += 'x' + std::to_string(step < 0 ? -step : step);
    i = j;
  }
  return out;
}

bool clip_frame_ranges(const std::string& spec, const std::string& shot, std::string& clipped,
                       std::string& error, size_t* dropped) {
  std::vector<int> wanted, in_shot;
  if (!parse_frame_ranges(spec, wanted, error)) return false;
  if (!parse_frame_ranges(shot, in_shot, error)) return false;
  std::sort(in_shot.begin(), in_shot.end());
  std::vector<int> kept;
  for (int f : wanted)
    if (std::binary_search(in_shot.begin(), in_shot.end(), f)) kept.push_back(f);
  clipped = format_frame_ranges(kept);
  if (dropped) *dropped = wanted.size() - kept.size();
  return true;
}

bool has_frame_pattern(const std::string& path) { return find_pattern(path).pos != std::string::npos; }

std::string expand_frame_pattern(const std::string& path, int frame) {
  const Pattern p = find_pattern(path);
  if (p.pos == std::string::npos) return path;
  // Zero-pad the magnitude to the pattern's width (the sign, if any, counts in it).
  std::string digits = std::to_string(frame < 0 ? -static_cast<long long>(frame) : frame);
  const size_t width = size_t(std::clamp(p.digits - (frame < 0 ? 1 : 0), 0, 32));
  if (digits.size() < width) digits.insert(0, width - digits.size(), '0');
  if (frame < 0) digits.insert(0, 1, '-');
  return path.substr(0, p.pos) + digits + path.substr(p.pos + p.length);
}

bool parse_chunk(const std::string& spec, int& index, int& count, std::string& error) {
  const size_t slash = spec.find('/');
  if (slash == std::string::npos || !parse_int(spec.substr(0, slash), index) ||
      !parse_int(spec.substr(slash + 1), count)) {
    error = "--chunk '" + spec + "': expected I/N, e.g. 2/8 for the second of 8 slices";
    return false;
  }
  if (count < 1) {
    error = "--chunk '" + spec + "': N, the number of chunks, must be at least 1";
    return false;
  }
  if (index < 1 || index > count) {
    error = "--chunk '" + spec + "': I must be between 1 and N (chunks count from 1)";
    return false;
  }
  return true;
}

}  // namespace ssdo
