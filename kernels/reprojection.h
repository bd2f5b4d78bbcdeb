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

// The view-space points of a camera's pixel centres (core/camera.h, PixelRays: the point at
// pixel coordinates (px, py) and planar depth d is o(px, py) + d u(px, py), both affine in
// (px, py)), carried by a rigid transform when asked, and the distance of those points from a
// plane as the same bilinear form: a few multiply-adds per pixel instead of a 2x2 solve.
class PixelPoints {
 public:
  explicit PixelPoints(const Camera& c) : rays_(pixel_rays(c)) {}

  // The point at the centre of pixel (x, y) with planar depth depth_view.
  glm::vec3 at(int x, int y, float depth_view) const {
    return rays_.point(float(x) + 0.5f, float(y) + 0.5f, depth_view);
  }

  // The same points carried by a rigid transform (into another camera's view space): the
  // translation enters the constant term only.
  PixelPoints transformed(const glm::mat4& rigid) const {
    const glm::mat3 r(rigid);
    PixelPoints t = *this;
    PixelRays& m = t.rays_;
    m.o0 = glm::vec3(rigid * glm::vec4(rays_.o0, 1.0f));
    m.ox = r * rays_.ox, m.oy = r * rays_.oy, m.u0 = r * rays_.u0, m.ux = r * rays_.ux, m.uy = r * rays_.uy;
    return t;
  }

  // n . (at(x, y, d) - p) for a fixed plane (point p, normal n), as a bilinear form in
  // (x + 0.5, y + 0.5, d): six numbers per plane.
  struct PlaneDistance {
    float c0, cx, cy, d0, dx, dy;
    float signed_at(int x, int y, float depth_view) const {
      const float px = float(x) + 0.5f, py = float(y) + 0.5f;
      return c0 + px * cx + py * cy + depth_view * (d0 + px * dx + py * dy);
    }
  };
  const PixelRays& rays() const { return rays_; }

  PlaneDistance plane(const glm::vec3& p, const glm::vec3& n) const {
    return {glm::dot(n, rays_.o0 - p), glm::dot(n, rays_.ox), glm::dot(n, rays_.oy),
            glm::dot(n, rays_.u0),     glm::dot(n, rays_.ux), glm::dot(n, rays_.uy)};
  }

 private:
  PixelRays rays_;
};

class Reprojection {
 public:
  // from, to: the two frames' cameras (the same world); both must outlive this object.
  Reprojection(const Camera& from, const Camera& to)
      : to_(&to),
        to_view_from_view_(to.world_to_view * from.view_to_world),
        from_points_in_to_(PixelPoints(from).transformed(to_view_from_view_)),
        to_points_(to) {}

  // Point p of `from` in `to`: its view-space position and normal there, its continuous
  // pixel coordinates in `to`'s grid (NaN when p is at or behind `to`'s eye), and the
  // distance from its tangent plane as a function of `to`'s pixels (plane_distance).
  struct Carried {
    glm::vec3 point_view;
    glm::vec3 normal_view;
    glm::vec2 pixel;
    PixelPoints::PlaneDistance plane;
  };

  // The surface seen at pixel (x, y) of `from` (its centre) at planar depth depth_view with
  // the unit view-space normal normal_view of `from`.
  Carried carry(int x, int y, float depth_view, const glm::vec3& normal_view) const {
    const glm::vec3 p_to = from_points_in_to_.at(x, y, depth_view);
    const glm::vec3 n_to(to_view_from_view_ * glm::vec4(normal_view, 0.0f));
    return {p_to, n_to, to_->pixel_from_view(p_to), to_points_.plane(p_to, n_to)};
  }

  // |n . (q - p)|: the distance of texel (tx, ty) of `to`, at its planar depth depth_view,
  // from the tangent plane of the carried point p, scene units.
  static float plane_distance(const Carried& p, int tx, int ty, float depth_view) {
    return std::abs(p.plane.signed_at(tx, ty, depth_view));
  }

  // What carry() is made of, for code that carries several points at once (in vector
  // lanes): from's pixel points in to's view space, the rotation that carries normals, and
  // the target camera (its projection and its own pixel points, for the plane distance).
  const PixelRays& from_rays_in_to() const { return from_points_in_to_.rays(); }
  glm::mat3 rotation() const { return glm::mat3(to_view_from_view_); }
  const Camera& to() const { return *to_; }
  const PixelRays& to_rays() const { return to_points_.rays(); }

 private:
  const Camera* to_;
  glm::mat4 to_view_from_view_;  // to.world_to_view * from.view_to_world (rigid)
  PixelPoints from_points_in_to_;  // from's pixel points, in to's view space
  PixelPoints to_points_;
};

}  // namespace ssdo
