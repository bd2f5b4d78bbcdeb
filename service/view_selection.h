// Which neighbouring frames of a shot a frame uses as extra views (GBuffer::views).
//
// A neighbour helps where it sees what this frame does not: its camera must have moved
// (or turned) relative to the scene. The measure is the parallax between two camera poses
// at the frame's scene depth d (the median foreground depth), in radians:
//   parallax(A, B) = |eye_A - eye_B| / d + angle(forward_A, forward_B)
// (the baseline's angle as seen from the scene, plus the turn of the view axis). On each
// side of the frame, walking outward from the nearest frame, a candidate is chosen when
// its parallax to the last chosen view (at first: the frame itself) reaches
// target_parallax, up to views_per_side; a side where nothing reaches it takes its
// farthest candidate that moved at least min_parallax (a slow dolly still gains a little).
// A static camera gets no views: a view from the same pose sees nothing new.
//
// Candidates that cannot be used are skipped with a note, never an error: no camera of
// its own (a bare --fov camera has no world), another resolution, or beyond a cut (a
// step between consecutive frames of more than cut_step_factor x the sequence's median
// step: the frames past it are another shot). A frame whose camera jumps away while the
// next frame continues the one before it has a wrong camera, not a cut: it alone is
// skipped.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace ssdo {

struct ViewSelectionSettings {
  int views_per_side = 0;          // K: at most this many views before and after the frame
  float target_parallax = 0.3f;    // radians between chosen views (~17 degrees: a new side of
                                   // an occluder; the orbit's 5-degree steps gained little at
                                   // +-1 frame and 16% at +-3)
  float min_parallax = 0.02f;      // radians: less is the same view (a static camera)
  float cut_step_factor = 8.0f;    // a step this many times the median step is a cut
};

// Candidates are looked at within this many frames per view on each side
// (window = kCandidateFramesPerView x K): wide enough that small steps still reach the
// target parallax.
inline constexpr int kCandidateFramesPerView = 3;

struct ViewCandidate {
  std::string name;          // for notes
  int frame_offset = 0;      // its frame number minus the frame's (never 0)
  bool has_camera = false;   // a camera with a world transform
  int width_px = 0, height_px = 0;
  glm::mat4 view_to_world{1.0f};  // its camera's pose
};

struct ViewChoice {
  std::vector<size_t> chosen;       // indices into the candidates, nearest first per side
  std::vector<std::string> notes;   // why candidates were skipped
};

// The parallax between two poses at scene depth `scene_depth_world` (> 0), radians.
float pose_parallax(const glm::mat4& view_to_world_a, const glm::mat4& view_to_world_b, float scene_depth_world);

// The views of a frame with pose `frame_view_to_world` and grid width_px x height_px,
// among `candidates` (any order). Pure: the same inputs give the same choice.
ViewChoice select_views(const glm::mat4& frame_view_to_world, int width_px, int height_px,
                        float scene_depth_world, const std::vector<ViewCandidate>& candidates,
                        const ViewSelectionSettings& settings);

}  // namespace ssdo
