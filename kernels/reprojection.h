// A surface point of one frame carried into another frame of the same scene (a neighbouring
// frame of a shot): lifted from its pixel centre and planar depth to the frame's view space,
// through the world into the other camera's view space, and projected into its pixel grid
// (core/camera.h). What the temporal filter (kernels/temporal.h) and the flicker metric
// (kernels/metrics.h) share, so that both call "the same surface" the same thing.
//
// Same surface: a texel of the other frame holds the surface of point p (unit normal n, both
// carried into the other frame's view space) when the texel's own point q lies on p's
// tangent plane,
//   |n . (q - p)| <= tolerance_relative * depth_p,
// a distance to the plane: unlike a difference of depths it does not grow with the surface's
// slope to either view, so a floor seen at a grazing angle agrees with itself while an
// occluder in front of it, or a surface that moved, does not. The normals must agree too
// (n . n_q > 0 at the least; callers weigh the agreement).
#pragma once

#include <cmath>

#include "core/camera.h"

namespace ssdo {

class Reprojection {
 public:
  // from, to: the two frames' cameras (the same world); both must outlive this object.
  Reprojection(const Camera& from, const Camera& to)
      : from_(&from), to_(&to), to_view_from_view_(to.world_to_view * from.view_to_world) {}

  // Point p of `from` in `to`: its view-space position and normal there, and its continuous
  // pixel coordinates in `to`'s grid (NaN when p is at or behind `to`'s eye).
  struct Carried {
    glm::vec3 point_view;
    glm::vec3 normal_view;
    glm::vec2 pixel;
  };

  // The surface seen at pixel (x, y) of `from` (its centre) at planar depth depth_view with
  // the unit view-space normal normal_view of `from`.
  Carried carry(int x, int y, float depth_view, const glm::vec3& normal_view) const {
    const glm::vec3 p_from = from_->view_from_pixel_depth(glm::vec2(float(x) + 0.5f, float(y) + 0.5f), depth_view);
    const glm::vec3 p_to(to_view_from_view_ * glm::vec4(p_from, 1.0f));
    const glm::vec3 n_to(to_view_from_view_ * glm::vec4(normal_view, 0.0f));
    return {p_to, n_to, to_->pixel_from_view(p_to)};
  }

  // |n . (q - p)|: the distance of texel (tx, ty) of `to`, at its planar depth depth_view,
  // from the tangent plane of the carried point p, scene units.
  float plane_distance(const Carried& p, int tx, int ty, float depth_view) const {
    const glm::vec3 q = to_->view_from_pixel_depth(glm::vec2(float(tx) + 0.5f, float(ty) + 0.5f), depth_view);
    return std::abs(glm::dot(p.normal_view, q - p.point_view));
  }

 private:
  const Camera* from_;
  const Camera* to_;
  glm::mat4 to_view_from_view_;  // to.world_to_view * from.view_to_world (rigid)
};

}  // namespace ssdo
