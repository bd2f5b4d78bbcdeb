// A neighbour's own neighbour list derived from a frame's (service/sequence.h): what lets a
// worker compute a temporal neighbour's raw terms exactly as the neighbour's own job does.
#include <algorithm>
#include <tuple>

#include <gtest/gtest.h>

#include "service/sequence.h"

namespace ssdo {
namespace {

std::vector<std::string> shot(int frames, int step) {
  std::vector<std::string> names;
  for (int i = 0; i < frames; ++i) names.push_back("in/shot." + std::to_string(1000 + i * step) + ".exr");
  return names;
}

std::vector<std::pair<std::string, int>> names_and_offsets(const std::vector<NeighbourFrame>& list) {
  std::vector<std::pair<std::string, int>> out;
  for (const NeighbourFrame& n : list) out.push_back({n.path, n.frame_offset});
  return out;
}

TEST(SequenceWindow, ANeighboursDerivedListIsItsOwn) {
  for (const int step : {1, 2, -2}) {
    std::vector<std::string> frames = shot(12, std::abs(step));
    if (step < 0) frames.erase(frames.begin() + 5);  // a failed frame in the middle
    const int views_places = 6, temporal = 2;
    const auto wide = sequence_neighbours(frames, neighbour_places(2, temporal));
    const auto own = sequence_neighbours(frames, views_places);
    for (size_t t = 0; t < frames.size(); ++t) {
      const NeighbourFrame self{frames[t], 0, false, {}, {}};
      // The frame's own view candidates: the wide list within the views' places.
      EXPECT_EQ(names_and_offsets(within_places(wide[t], views_places)), names_and_offsets(own[t])) << t;
      for (const NeighbourFrame& n : within_places(wide[t], temporal)) {
        const size_t u = size_t(std::find(frames.begin(), frames.end(), n.path) - frames.begin());
        EXPECT_EQ(names_and_offsets(neighbours_of_neighbour(self, wide[t], n, views_places)), names_and_offsets(own[u]))
            << "frame " << t << ", neighbour " << u;
      }
    }
  }
}

// The frame number of a name: the run of digits standing alone between separators, not a
// version tag's; negative after a separator; the last run of digits otherwise.
TEST(SequenceWindow, AFramesNumberIsTheOneBetweenSeparators) {
  const std::vector<std::tuple<std::string, std::string, long>> cases = {
      {"in/shot.0012.exr", "in/shot.#.exr", 12},      {"in/shot.0012.v2.exr", "in/shot.#.v2.exr", 12},
      {"in/take2_0012.exr", "in/take2_#.exr", 12},    {"in/orbit_f3.exr", "in/orbit_f#.exr", 3},
      {"in/frame0012.exr", "in/frame#.exr", 12},      {"in/shot.-003.exr", "in/shot.#.exr", -3},
      {"in/shot-0003.exr", "in/shot-#.exr", 3},       {"in/render_2k.0004.exr", "in/render_2k.#.exr", 4},
  };
  for (const auto& [path, sequence, number] : cases) {
    const auto place = sequence_place(path);
    ASSERT_TRUE(place) << path;
    EXPECT_EQ(place->sequence, sequence) << path;
    EXPECT_EQ(place->number, number) << path;
  }
  EXPECT_FALSE(sequence_place("in/beauty.exr"));
  // Frames -1 and 0 of one shot are neighbours, in frame order.
  const auto lists = sequence_neighbours({"s/shot.-002.exr", "s/shot.-001.exr", "s/shot.0000.exr", "s/shot.0001.exr"}, 1);
  EXPECT_EQ(names_and_offsets(lists[1]),
            (std::vector<std::pair<std::string, int>>{{"s/shot.-002.exr", -1}, {"s/shot.0000.exr", 1}}));
  EXPECT_EQ(names_and_offsets(lists[2]),
            (std::vector<std::pair<std::string, int>>{{"s/shot.-001.exr", -1}, {"s/shot.0001.exr", 1}}));
}

// A request's "views" as a client may send them: the whole shot with the frame itself,
// or a view twice. Each view counts once and the frame is not its own view; the list is in
// sequence_neighbours' order (nearest first, earlier first), whatever order they came in.
TEST(SequenceWindow, NamedViewsLeaveOutTheFrameAndRepeats) {
  const std::vector<std::pair<std::string, int>> expected = {{"in/shot.0999.exr", -1}, {"in/shot.1001.exr", 1}};
  EXPECT_EQ(names_and_offsets(named_neighbours("in/shot.1000.exr", {"in/shot.1001.exr", "in/shot.1000.exr",
                                                                    "in/shot.1001.exr", "in/shot.0999.exr",
                                                                    "in/shot.1001.exr"})),
            expected);
  // The order of a batch's list, from any order given.
  const std::vector<std::string> shot = {"in/shot.0998.exr", "in/shot.0999.exr", "in/shot.1000.exr",
                                         "in/shot.1001.exr", "in/shot.1002.exr"};
  EXPECT_EQ(names_and_offsets(named_neighbours("in/shot.1000.exr", {"in/shot.1002.exr", "in/shot.1001.exr",
                                                                    "in/shot.0998.exr", "in/shot.0999.exr"})),
            names_and_offsets(sequence_neighbours(shot, 2)[2]));
  // Outside a sequence: 1, 2, ... in the order given, repeats left out before counting.
  const std::vector<std::pair<std::string, int>> loose = {{"b.exr", 1}, {"c.exr", 2}};
  EXPECT_EQ(names_and_offsets(named_neighbours("a.exr", {"b.exr", "b.exr", "a.exr", "c.exr"})), loose);
}

// A place is a frame of the sequence whether or not its file is there: a folder missing a
// frame gives the frames around the gap the neighbours a pattern over the whole range
// gives them (less the missing file), not frames from beyond the gap; a shot rendered on
// twos counts every second frame as the next place; a second file of one frame number
// ("s.1" beside "s.0001") is no other frame.
TEST(SequenceWindow, AMissingFrameIsAPlace) {
  using Offsets = std::vector<std::pair<std::string, int>>;
  const std::vector<std::string> whole = {"h/o_f0.exr", "h/o_f1.exr", "h/o_f2.exr", "h/o_f3.exr",
                                          "h/o_f4.exr", "h/o_f5.exr", "h/o_f6.exr"};
  std::vector<std::string> folder = whole;
  folder.erase(folder.begin() + 3);
  const auto from_pattern = sequence_neighbours(whole, 2);
  const auto from_folder = sequence_neighbours(folder, 2);
  EXPECT_EQ(names_and_offsets(from_folder[4]), (Offsets{{"h/o_f4.exr", -1}, {"h/o_f6.exr", 1}}));  // frame 5
  EXPECT_EQ(names_and_offsets(from_folder[2]), (Offsets{{"h/o_f1.exr", -1}, {"h/o_f0.exr", -2}, {"h/o_f4.exr", 2}}));
  for (size_t i = 0; i < folder.size(); ++i) {
    const size_t w = size_t(std::find(whole.begin(), whole.end(), folder[i]) - whole.begin());
    Offsets expected;
    for (const NeighbourFrame& n : from_pattern[w])
      if (n.path != "h/o_f3.exr") expected.push_back({n.path, n.frame_offset});
    EXPECT_EQ(names_and_offsets(from_folder[i]), expected) << folder[i];
  }
  // On twos, with frame 6 missing: 8 is two places after 4.
  const auto twos = sequence_neighbours({"t/s.0000.exr", "t/s.0002.exr", "t/s.0004.exr", "t/s.0008.exr"}, 2);
  EXPECT_EQ(names_and_offsets(twos[3]), (Offsets{{"t/s.0004.exr", -2}}));
  EXPECT_EQ(names_and_offsets(twos[1]), (Offsets{{"t/s.0000.exr", -1}, {"t/s.0004.exr", 1}}));
  // Negative frame numbers on twos keep their places apart.
  const auto negative = sequence_neighbours({"n/s.-003.exr", "n/s.-001.exr", "n/s.0001.exr"}, 1);
  EXPECT_EQ(names_and_offsets(negative[1]), (Offsets{{"n/s.-003.exr", -1}, {"n/s.0001.exr", 1}}));
  // Two files of frame 1: the first is the frame; frame 3 keeps frame 1 as its second place.
  const auto twice = sequence_neighbours({"d/s.0.exr", "d/s.1.exr", "d/s.2.exr", "d/s.3.exr", "d/s.0001.exr"}, 2);
  EXPECT_EQ(names_and_offsets(twice[0]), (Offsets{{"d/s.1.exr", 1}, {"d/s.2.exr", 2}}));
  EXPECT_EQ(names_and_offsets(twice[3]), (Offsets{{"d/s.2.exr", -1}, {"d/s.1.exr", -2}}));
}

TEST(SequenceWindow, Places) {
  EXPECT_EQ(view_candidate_places(2), 6);
  EXPECT_EQ(neighbour_places(2, 0), 6);
  EXPECT_EQ(neighbour_places(2, 2), 8);
  EXPECT_EQ(neighbour_places(0, 3), 3);
  EXPECT_EQ(neighbour_places(0, 0), 0);
}

}  // namespace
}  // namespace ssdo
