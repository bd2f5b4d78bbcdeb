#include "service/view_selection.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace ssdo {

namespace {

// The usable candidates of one side, nearest first, as indices; the others noted.
struct Side {
  std::vector<size_t> usable;
};

float median(std::vector<float> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Candidates of one side (sign +1 after, -1 before), nearest first, that have a camera
// and the frame's grid.
std::vector<size_t> consistent_side(const std::vector<ViewCandidate>& c, int sign, int width_px, int height_px,
                                    ViewChoice& choice) {
  std::vector<size_t> side;
  for (size_t i = 0; i < c.size(); ++i) {
    if (c[i].frame_offset * sign <= 0) continue;
    if (!c[i].has_camera) {
      choice.notes.push_back(c[i].name + ": skipped as a view (no camera with a world transform)");
    } else if (c[i].width_px != width_px || c[i].height_px != height_px) {
      choice.notes.push_back(c[i].name + ": skipped as a view (" + std::to_string(c[i].width_px) + "x" +
                             std::to_string(c[i].height_px) + ", the frame is " + std::to_string(width_px) + "x" +
                             std::to_string(height_px) + ")");
    } else {
      side.push_back(i);
    }
  }
  std::sort(side.begin(), side.end(),
            [&](size_t a, size_t b) { return std::abs(c[a].frame_offset) < std::abs(c[b].frame_offset); });
  return side;
}

// The parallax of each step outward along a side: from the frame to the nearest, then
// between consecutive candidates.
std::vector<float> side_steps(const glm::mat4& frame, const std::vector<ViewCandidate>& c,
                              const std::vector<size_t>& side, float depth) {
  std::vector<float> steps;
  const glm::mat4* previous = &frame;
  for (size_t i : side) {
    steps.push_back(pose_parallax(*previous, c[i].view_to_world, depth));
    previous = &c[i].view_to_world;
  }
  return steps;
}

// Drops the candidates at and beyond the first step that is a cut (a step over `cut_step`;
// `median_step`: the shot's, in the note). A candidate whose camera jumps away while the
// next one is within `cut_step` of the pose before it is no cut but one frame with a wrong
// camera: only that frame is dropped.
void cut_side(std::vector<size_t>& side, const std::vector<float>& steps, float cut_step, float median_step,
              const glm::mat4& frame, float depth, const std::vector<ViewCandidate>& c, ViewChoice& choice) {
  std::vector<size_t> kept;
  const glm::mat4* previous = &frame;
  for (size_t k = 0; k < side.size(); ++k) {
    const float step = kept.size() == k ? steps[k] : pose_parallax(*previous, c[side[k]].view_to_world, depth);
    if (step <= cut_step) {
      kept.push_back(side[k]);
      previous = &c[side[k]].view_to_world;
      continue;
    }
    if (k + 1 < side.size() && pose_parallax(*previous, c[side[k + 1]].view_to_world, depth) <= cut_step) {
      choice.notes.push_back(c[side[k]].name + ": skipped as a view (its camera jumps " + std::to_string(step) +
                             " rad away and the next frame's is back: a wrong camera for this frame?)");
      continue;
    }
    choice.notes.push_back(c[side[k]].name + ": skipped as a view with the frames beyond it (a cut: the camera " +
                           "jumps " + std::to_string(step) + " rad, over the cut threshold of " +
                           std::to_string(cut_step) + " rad; the shot's median step is " +
                           std::to_string(median_step) + " rad)");
    break;
  }
  side = kept;
}

// The walk outward described in the header, on one side.
void choose_side(const glm::mat4& frame, const std::vector<ViewCandidate>& c, const std::vector<size_t>& side,
                 float depth, const ViewSelectionSettings& s, ViewChoice& choice) {
  const glm::mat4* last = &frame;
  int taken = 0;
  for (size_t i : side) {
    if (taken == s.views_per_side) break;
    if (pose_parallax(*last, c[i].view_to_world, depth) < s.target_parallax) continue;
    choice.chosen.push_back(i);
    last = &c[i].view_to_world;
    ++taken;
  }
  if (taken > 0 || side.empty() || s.views_per_side == 0) return;
  const size_t farthest = side.back();
  if (pose_parallax(frame, c[farthest].view_to_world, depth) >= s.min_parallax) choice.chosen.push_back(farthest);
}

}  // namespace

float pose_parallax(const glm::mat4& a, const glm::mat4& b, float scene_depth_world) {
  const float baseline = glm::length(glm::vec3(a[3]) - glm::vec3(b[3]));
  // Forward = -Z of view space, in world space: the third column of view_to_world, negated.
  const glm::vec3 fa = glm::normalize(-glm::vec3(a[2])), fb = glm::normalize(-glm::vec3(b[2]));
  const float turn = std::acos(std::clamp(glm::dot(fa, fb), -1.0f, 1.0f));
  return baseline / std::max(scene_depth_world, 1e-6f) + turn;
}

ViewChoice select_views(const glm::mat4& frame, int width_px, int height_px, float depth,
                        const std::vector<ViewCandidate>& candidates, const ViewSelectionSettings& s) {
  ViewChoice choice;
  if (s.views_per_side <= 0 || candidates.empty()) return choice;
  std::vector<size_t> sides[2] = {consistent_side(candidates, -1, width_px, height_px, choice),
                                  consistent_side(candidates, +1, width_px, height_px, choice)};
  std::vector<float> steps[2], all_steps;
  for (int k = 0; k < 2; ++k) {
    steps[k] = side_steps(frame, candidates, sides[k], depth);
    all_steps.insert(all_steps.end(), steps[k].begin(), steps[k].end());
  }
  // A cut is a step far beyond the shot's typical one; for a static camera (median 0) any
  // step that is more than a view's worth of motion.
  const float median_step = median(all_steps);
  const float cut_step = std::max(s.cut_step_factor * median_step, s.min_parallax);
  for (int k = 0; k < 2; ++k) {
    cut_side(sides[k], steps[k], cut_step, median_step, frame, depth, candidates, choice);
    choose_side(frame, candidates, sides[k], depth, s, choice);
  }
  return choice;
}

}  // namespace ssdo
