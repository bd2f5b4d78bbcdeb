// Frame numbers, frame-file patterns and farm chunks, as render farms and oiiotool
// spell them:
//   ranges   "1-100x2,200"  = 1,3,...,99,200 ("A-B" inclusive, "xN" step N, "A" alone);
//            clipped to a shot's range for farm tasks that overshoot it
//   patterns "shot.####.exr" (a run of N '#' = N digits; a lone '#' = 4 digits, oiiotool's
//            convention), "shot.@@@.exr" (one digit per '@'), "shot.%04d.exr" (printf)
//   chunks   "I/N"  = the I-th (1-based) of N near-equal consecutive slices of the list
#pragma once

#include <string>
#include <vector>

namespace ssdo {

// Appends the frames of `spec` to `frames`. At most `max_frames` in total (a guard
// against "1-999999999"). False with a message naming the bad part on error.
bool parse_frame_ranges(const std::string& spec, std::vector<int>& frames, std::string& error,
                        size_t max_frames = 1000000);

// The shortest spelling of `frames` that parse_frame_ranges reads back as the same list
// (same order): runs with a constant step become "A-B" / "A-BxN", e.g. {1,2,3,5,7,9,12}
// -> "1-3,5-9x2,12". "" for an empty list.
std::string format_frame_ranges(const std::vector<int>& frames);

// The frames of `spec` that are also frames of `shot`, in spec's order, spelled by
// format_frame_ranges ("" when none is): "21-25" within "1-24" is "21-24". For farm tasks
// whose frame range runs past the shot's end (the last chunk of a shot whose length is
// not a multiple of the chunk size). False with a message on a malformed spec or shot.
// `dropped` (optional): how many frames of `spec` were outside the shot.
bool clip_frame_ranges(const std::string& spec, const std::string& shot, std::string& clipped,
                       std::string& error, size_t* dropped = nullptr);

// True when `path` holds a frame-number pattern.
bool has_frame_pattern(const std::string& path);

// `path` with its (first) frame pattern replaced by `frame`, zero-padded.
std::string expand_frame_pattern(const std::string& path, int frame);

// Parses "I/N" (1 <= I <= N). False with a message on error.
bool parse_chunk(const std::string& spec, int& index, int& count, std::string& error);

// The index-th (1-based) of `count` near-equal consecutive slices of `items`: slice i
// holds items [floor((i-1) F / count), floor(i F / count)) of F items, so slices never
// overlap, cover everything, and differ in size by at most one.
template <typename T>
std::vector<T> chunk_slice(const std::vector<T>& items, int index, int count) {
  const size_t f = items.size();
  const size_t begin = f * size_t(index - 1) / size_t(count);
  const size_t end = f * size_t(index) / size_t(count);
  return std::vector<T>(items.begin() + begin, items.begin() + end);
}

}  // namespace ssdo
