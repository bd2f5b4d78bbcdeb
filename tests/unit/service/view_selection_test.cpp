#include "service/view_selection.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

namespace ssdo {
namespace {

constexpr int kWidth = 64, kHeight = 48;
constexpr float kPi = 3.14159265f;

// A camera on a circle of radius 4 around the origin, looking at it, at `deg` degrees.
glm::mat4 orbit_pose(float deg) {
  const float a = deg * kPi / 180.0f;
  const glm::vec3 eye(4.0f * std::sin(a), 1.0f, 4.0f * std::cos(a));
  return glm::inverse(glm::lookAt(eye, glm::vec3(0), glm::vec3(0, 1, 0)));
}

glm::mat4 truck_pose(float x) {
  return glm::inverse(glm::lookAt(glm::vec3(x, 1, 4), glm::vec3(x, 1, 0), glm::vec3(0, 1, 0)));
}

// Candidates at offsets -window..window (0 excluded) with pose(offset).
template <class Pose>
std::vector<ViewCandidate> sequence(int window, Pose pose) {
  std::vector<ViewCandidate> c;
  for (int o = -window; o <= window; ++o) {
    if (o == 0) continue;
    c.push_back({"f" + std::to_string(o), o, true, kWidth, kHeight, pose(o)});
  }
  return c;
}

std::vector<int> offsets(const std::vector<ViewCandidate>& c, const ViewChoice& choice) {
  std::vector<int> o;
  for (size_t i : choice.chosen) o.push_back(c[i].frame_offset);
  std::sort(o.begin(), o.end());
  return o;
}

ViewSelectionSettings views(int k) {
  ViewSelectionSettings s;
  s.views_per_side = k;
  return s;
}

TEST(ViewSelection, ParallaxIsBaselineOverDepthPlusTurn) {
  EXPECT_NEAR(pose_parallax(truck_pose(0), truck_pose(0.4f), 4.0f), 0.1f, 1e-5f);
  EXPECT_NEAR(pose_parallax(truck_pose(0), truck_pose(0), 4.0f), 0.0f, 1e-6f);
  // Turning in place by 10 degrees: no baseline, the turn.
  const glm::mat4 turned = glm::rotate(truck_pose(0), 10.0f * kPi / 180.0f, glm::vec3(0, 1, 0));
  EXPECT_NEAR(pose_parallax(truck_pose(0), turned, 4.0f), 10.0f * kPi / 180.0f, 1e-4f);
}

TEST(ViewSelection, StaticCameraGetsNoViews) {
  const auto c = sequence(6, [](int) { return truck_pose(0); });
  const ViewChoice choice = select_views(truck_pose(0), kWidth, kHeight, 4.0f, c, views(2));
  EXPECT_TRUE(choice.chosen.empty());
  EXPECT_TRUE(choice.notes.empty());
}

TEST(ViewSelection, ZeroViewsPerSideChoosesNothing) {
  const auto c = sequence(3, [](int o) { return orbit_pose(5.0f * float(o)); });
  EXPECT_TRUE(select_views(orbit_pose(0), kWidth, kHeight, 4.0f, c, views(0)).chosen.empty());
}

TEST(ViewSelection, OrbitPicksSpreadFramesNotOnlyTheNearest) {
  // 5 degrees per frame: each step is ~0.087 rad of baseline at depth 4 plus 0.087 of turn.
  const auto c = sequence(6, [](int o) { return orbit_pose(5.0f * float(o)); });
  const ViewChoice two = select_views(orbit_pose(0), kWidth, kHeight, 4.0f, c, views(2));
  EXPECT_EQ(offsets(c, two), (std::vector<int>{-4, -2, 2, 4}));
  const ViewChoice one = select_views(orbit_pose(0), kWidth, kHeight, 4.0f, c, views(1));
  EXPECT_EQ(offsets(c, one), (std::vector<int>{-2, 2}));
}

TEST(ViewSelection, FastMoveTakesTheNearestFrames) {
  // 0.8 units per frame at depth 2: every step is 0.4 rad, beyond the target.
  const auto c = sequence(3, [](int o) { return truck_pose(0.8f * float(o)); });
  EXPECT_EQ(offsets(c, select_views(truck_pose(0), kWidth, kHeight, 2.0f, c, views(1))), (std::vector<int>{-1, 1}));
}

TEST(ViewSelection, SlowDollyTakesTheFarthestFrameThatMoved) {
  // 0.02 units per frame at depth 4 (0.005 rad per frame): nothing reaches the target, the
  // farthest of the window (0.03 rad) is still a little new.
  const auto c = sequence(6, [](int o) { return truck_pose(0.02f * float(o)); });
  EXPECT_EQ(offsets(c, select_views(truck_pose(0), kWidth, kHeight, 4.0f, c, views(2))), (std::vector<int>{-6, 6}));
}

TEST(ViewSelection, InconsistentNeighboursAreSkippedWithANote) {
  auto c = sequence(2, [](int o) { return truck_pose(0.8f * float(o)); });
  c[1].has_camera = false;   // offset -1
  c[2].width_px = 32;        // offset +1
  const ViewChoice choice = select_views(truck_pose(0), kWidth, kHeight, 2.0f, c, views(1));
  EXPECT_EQ(offsets(c, choice), (std::vector<int>{-2, 2}));
  ASSERT_EQ(choice.notes.size(), 2u);
  EXPECT_NE(choice.notes[0].find("f-1: skipped as a view (no camera"), std::string::npos) << choice.notes[0];
  EXPECT_NE(choice.notes[1].find("f1: skipped as a view (32x48, the frame is 64x48)"), std::string::npos)
      << choice.notes[1];
}

TEST(ViewSelection, ACutEndsTheSide) {
  // A truck of 0.8 per frame, then from frame +2 on another shot 50 units away.
  const auto c = sequence(4, [](int o) { return truck_pose(o >= 2 ? 50.0f + float(o) : 0.8f * float(o)); });
  const ViewChoice choice = select_views(truck_pose(0), kWidth, kHeight, 2.0f, c, views(4));
  EXPECT_EQ(offsets(c, choice), (std::vector<int>{-4, -3, -2, -1, 1}));
  ASSERT_EQ(choice.notes.size(), 1u);
  EXPECT_NE(choice.notes[0].find("f2: skipped as a view with the frames beyond it (a cut"), std::string::npos)
      << choice.notes[0];
  // The note gives the threshold as the threshold and the median step as the median.
  const std::string& note = choice.notes[0];
  const size_t over = note.find("over the cut threshold of "), median = note.find("the shot's median step is ");
  ASSERT_NE(over, std::string::npos) << note;
  ASSERT_NE(median, std::string::npos) << note;
  const float threshold = std::stof(note.substr(over + 26)), median_step = std::stof(note.substr(median + 26));
  EXPECT_GT(median_step, 0.0f) << note;
  EXPECT_FLOAT_EQ(threshold, std::max(8.0f * median_step, ViewSelectionSettings{}.min_parallax)) << note;
}

// One frame with a wrong camera (another shot's) between frames that continue each other
// is no cut: only that frame is skipped, and the frames beyond it stay views.
TEST(ViewSelection, OneFrameWithAWrongCameraIsNoCut) {
  const auto c = sequence(4, [](int o) { return truck_pose(o == 2 ? 50.0f : 0.8f * float(o)); });
  const ViewChoice choice = select_views(truck_pose(0), kWidth, kHeight, 2.0f, c, views(4));
  EXPECT_EQ(offsets(c, choice), (std::vector<int>{-4, -3, -2, -1, 1, 3, 4}));
  ASSERT_EQ(choice.notes.size(), 1u);
  EXPECT_NE(choice.notes[0].find("f2: skipped as a view (its camera jumps"), std::string::npos) << choice.notes[0];
  // The wrong camera on the nearest frame: the same.
  const auto near = sequence(3, [](int o) { return truck_pose(o == 1 ? 50.0f : 0.8f * float(o)); });
  EXPECT_EQ(offsets(near, select_views(truck_pose(0), kWidth, kHeight, 2.0f, near, views(3))),
            (std::vector<int>{-3, -2, -1, 2, 3}));
}

}  // namespace
}  // namespace ssdo
