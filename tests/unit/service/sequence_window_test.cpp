// A neighbour's own neighbour list derived from a frame's (service/sequence.h): what lets a
// worker compute a temporal neighbour's raw terms exactly as the neighbour's own job does.
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
