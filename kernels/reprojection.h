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

#include <algorithm>
#include <cmath>

#include "core/camera.h"

namespace ssdo {

// Camera::view_from_pixel_depth at pixel centres, evaluated as the bilinear form it is: for
// every camera whose clip.w does not depend on x and y (core/camera.h), the view-space point
// at continuous pixel coordinates (u, v) and planar depth d is
//   p = a0 + u a_u + v a_v + d (b0 + u b_u + v b_v),
// so a pixel's point costs a few multiply-adds instead of a 2x2 solve. The coefficients are
// taken from view_from_pixel_depth itself at the grid's corners and depths 1 and 2 (far
// apart, so that the differences keep their precision).
class PixelPoints {
 public:
  explicit PixelPoints(const Camera& c) {
    const float w = float(std::max(c.width_px, 2)), h = float(std::max(c.height_px, 2));
    const glm::vec2 o(0.5f, 0.5f), u(w - 0.5f, 0.5f), v(0.5f, h - 0.5f);
    auto ray = [&](glm::vec2 pixel, glm::vec3& a, glm::vec3& b) {
      const glm::vec3 p1 = c.view_from_pixel_depth(pixel, 1.0f);
      b = c.view_from_pixel_depth(pixel, 2.0f) - p1;
      a = p1 - b;
    };
    glm::vec3 a_o, b_o, a_u, b_u, a_v, b_v;
    ray(o, a_o, b_o), ray(u, a_u, b_u), ray(v, a_v, b_v);
    a_du_ = (a_u - a_o) / (w - 1.0f), b_du_ = (b_u - b_o) / (w - 1.0f);
    a_dv_ = (a_v - a_o) / (h - 1.0f), b_dv_ = (b_v - b_o) / (h - 1.0f);
    a0_ = a_o - 0.5f * (a_du_ + a_dv_), b0_ = b_o - 0.5f * (b_du_ + b_dv_);
  }
  // The point at the centre of pixel (x, y) with planar depth depth_view.
  glm::vec3 at(int x, int y, float depth_view) const {
    const float u = float(x) + 0.5f, v = float(y) + 0.5f;
    return a0_ + u * a_du_ + v * a_dv_ + depth_view * (b0_ + u * b_du_ + v * b_dv_);
  }

  // The same points carried by a rigid transform (into another camera's view space): the
  // form of the transformed points, the translation in the constant term only.
  PixelPoints transformed(const glm::mat4& rigid) const {
    const glm::mat3 r(rigid);
    PixelPoints t = *this;
    t.a0_ = glm::vec3(rigid * glm::vec4(a0_, 1.0f));
    t.a_du_ = r * a_du_, t.a_dv_ = r * a_dv_, t.b0_ = r * b0_, t.b_du_ = r * b_du_, t.b_dv_ = r * b_dv_;
    return t;
  }

  // n . (at(x, y, d) - p) for a fixed plane (point p, normal n) as the same bilinear form
  // in (x + 0.5, y + 0.5, d): six numbers per plane, then a few multiply-adds per pixel.
  struct PlaneDistance {
    float c0, cu, cv, d0, du, dv;
    float signed_at(int x, int y, float depth_view) const {
      const float u = float(x) + 0.5f, v = float(y) + 0.5f;
      return c0 + u * cu + v * cv + depth_view * (d0 + u * du + v * dv);
    }
  };
  PlaneDistance plane(const glm::vec3& p, const glm::vec3& n) const {
    return {glm::dot(n, a0_ - p), glm::dot(n, a_du_), glm::dot(n, a_dv_),
            glm::dot(n, b0_),     glm::dot(n, b_du_), glm::dot(n, b_dv_)};
  }

 private:
  glm::vec3 a0_, a_du_, a_dv_, b0_, b_du_, b_dv_;
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

 private:
  const Camera* to_;
  glm::mat4 to_view_from_view_;  // to.world_to_view * from.view_to_world (rigid)
  PixelPoints from_points_in_to_;  // from's pixel points, in to's view space
  PixelPoints to_points_;
};

}  // namespace ssdo
