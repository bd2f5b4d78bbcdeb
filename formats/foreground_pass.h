// The pass after reading a G-buffer, per row: depth classified as foreground or background
// and made planar, normals turned to view space, unit length and facing the camera. Part of
// the G-buffer reader (gbuffer_reader.cpp), in its own file because its row loop is compiled
// once per instruction set and dispatched at run time (core/simd.h).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/glm.hpp>
#include <opencv2/core.hpp>

namespace ssdo::foreground {

// Depth at or beyond this is background: renderers write "no hit" as a huge finite value
// (Cycles: 1e10, see ../shared/gbuffers/README.md) rather than +inf.
inline constexpr float kBackgroundDepth = 1e9f;
// Depth below this is no surface either: no renderer's near clip comes within orders of
// it, and the kernels divide by depth and by products of depths (reconstructed normals,
// the denoise's depth scale), which overflow to inf below ~1e-19.
inline constexpr float kMinForegroundDepth = 1e-10f;
// A stored normal shorter than this is "no normal" (Cycles writes (0, 0, 0) where it has
// none); unit normals in half precision are ~1 +- 1e-3.
inline constexpr float kMinNormalLength = 1e-6f;

// One row's share of what read_gbuffer reports.
struct RowCounts {
  int64_t foreground = 0, nonfinite = 0, repaired = 0;
  // Foreground pixels whose usable normal pointed away from the eye (in view space) and was
  // turned around.
  int64_t facing_away = 0;
  float depth_min = std::numeric_limits<float>::infinity();
  float depth_max = -std::numeric_limits<float>::infinity();
};

// What the pass after reading needs besides the row's pixels (see foreground_row).
struct ForegroundPass {
  int width = 0;
  float far_view = 0.0f;
  bool has_background = false;
  float background = 0.0f;
  bool radial = false, perspective = false, normals_world = false;
  glm::mat3 normal_to_view{1.0f};
  glm::vec3 ray_step_x{0.0f};
  glm::vec3 ray_origin{0.0f}, ray_step_y{0.0f};  // the ray through pixel (0, 0), per row
};

// The eye ray through the first pixel centre of row y (see eye_ray).
inline glm::vec3 row_ray(const ForegroundPass& pass, int y) {
  return pass.ray_origin + float(y) * pass.ray_step_y;
}

// The eye ray through pixel x of the row whose first ray is `ray_row` (length arbitrary,
// z = -1 in perspective).
inline glm::vec3 eye_ray(const ForegroundPass& pass, const glm::vec3& ray_row, int x) {
  return pass.perspective ? ray_row + float(x) * pass.ray_step_x : glm::vec3(0.0f, 0.0f, -1.0f);
}

// A stored depth sample as planar depth, or +inf when it is background: non-finite, below
// kMinForegroundDepth (0 and negative included), >= kBackgroundDepth, beyond the far clip
// or the sidecar's background value. Radial distance from the eye -> planar depth along
// -Z: d_planar = d cos(angle to the axis) = d / |ray| for a ray with z = -1.
inline float planar_depth(const ForegroundPass& pass, const glm::vec3& ray, float stored) {
  const float inf = std::numeric_limits<float>::infinity();
  if (!std::isfinite(stored)) return inf;
  float d = stored;
  if (pass.radial && pass.perspective) d /= glm::length(ray);
  const bool foreground = d >= kMinForegroundDepth && d < kBackgroundDepth &&
                          !(pass.far_view > 0.0f && d > pass.far_view) &&
                          !(pass.has_background && stored == pass.background);
  return foreground ? d : inf;
}

// The pointers of one row: `normal` and `repair` are null without normals.
struct ForegroundRow {
  float* depth;
  uint8_t* mask;
  cv::Vec3f* normal;
  uint8_t* repair;
};

// The pass after reading, one row: depth (radial -> planar) classified as foreground or
// not, normals to view space, unit length and facing the camera. `ray_row` is the eye ray
// through the row's first pixel centre. Background and unusable pixels get depth +inf,
// mask 0 and normal (0, 0, 0); foreground pixels mask 255, and repair 1 where the normal
// is (0, 0, 0); normals turned around are counted (RowCounts::facing_away). `pass` and
// `row` are taken by value: the mask's byte stores may alias anything behind a reference,
// which would be reloaded per pixel.
RowCounts foreground_row(ForegroundPass pass, glm::vec3 ray_row, ForegroundRow row);

}  // namespace ssdo::foreground
