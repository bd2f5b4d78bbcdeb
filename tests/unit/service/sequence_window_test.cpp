// A neighbour's own neighbour list derived from a frame's (service/sequence.h): what lets a
// worker compute a temporal neighbour's raw terms exactly as the neighbour's own job does.
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
  for (const int step : {1, 2}) {
    const std::vector<std::string> frames = shot(12, step);
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
// or a view twice. Each view counts once and the frame is not its own view.
TEST(SequenceWindow, NamedViewsLeaveOutTheFrameAndRepeats) {
  const std::vector<std::pair<std::string, int>> expected = {{"in/shot.1001.exr", 1}, {"in/shot.0999.exr", -1}};
  EXPECT_EQ(names_and_offsets(named_neighbours("in/shot.1000.exr", {"in/shot.1001.exr", "in/shot.1000.exr",
                                                                    "in/shot.1001.exr", "in/shot.0999.exr",
                                                                    "in/shot.1001.exr"})),
            expected);
  // Outside a sequence: 1, 2, ... in the order given, repeats left out before counting.
  const std::vector<std::pair<std::string, int>> loose = {{"b.exr", 1}, {"c.exr", 2}};
  EXPECT_EQ(names_and_offsets(named_neighbours("a.exr", {"b.exr", "b.exr", "a.exr", "c.exr"})), loose);
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
