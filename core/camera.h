// The camera every kernel works with: an OpenGL-style projection plus the
// world <-> view transforms, and the pixel grid of the frame.
//
// Conventions (docs/architecture.md, "Conventions"; converted once, in formats/):
// - View space: right-handed, camera at the origin looking down -Z, +Y up, +X right.
// - Planar depth: depth_view = -z_view > 0 (distance along the view axis).
// - Pixel coordinates are continuous: pixel (i, j) covers [i, i+1) x [j, j+1) and has
//   its centre at (i + 0.5, j + 0.5); row 0 is the top scanline of the data window.
// - ndc_x = 2 x_px / W - 1, ndc_y = 1 - 2 y_px / H (so the top row has ndc_y ~ +1).
// - clip = view_to_clip * [x, y, z, 1]; ndc = clip.xyz / clip.w. The full matrix is kept
//   (lens shift, non-square pixels and orthographic cameras are all expressible).
#pragma once

#include <cmath>

#include <glm/glm.hpp>

namespace ssdo {

struct Camera {
  int width_px = 0;   // data window width, pixels
  int height_px = 0;  // data window height, pixels
  glm::mat4 view_to_clip{1.0f};   // OpenGL-style projection (glm is column-major: m[col][row])
  glm::mat4 world_to_view{1.0f};  // rigid transform world -> view
  glm::mat4 view_to_world{1.0f};  // inverse of world_to_view
  float near_view = 0.0f;         // near clip distance, scene units (0 = unknown)
  float far_view = 0.0f;          // far clip distance, scene units (0 = unknown)

  // A symmetric perspective camera from the full horizontal field of view (degrees), with
  // pixels pixel_aspect times as wide as they are tall (OpenEXR's pixelAspectRatio; 1 =
  // square). near/far only fill the projection's depth rows.
  static Camera from_fov_x(int width_px, int height_px, float fov_x_deg,
                           float near_view = 0.05f, float far_view = 1000.0f, float pixel_aspect = 1.0f);

  bool is_perspective() const { return view_to_clip[2][3] != 0.0f; }

  // Full fields of view in degrees, from the projection's scale terms.
  float fov_x_deg() const;
  float fov_y_deg() const;

  glm::vec2 ndc_from_pixel(glm::vec2 pixel) const;
  glm::vec2 pixel_from_ndc(glm::vec2 ndc) const;

  // Projects a view-space point to continuous pixel coordinates. Points at or behind
  // the eye (w <= 0) return NaN coordinates.
  glm::vec2 pixel_from_view(const glm::vec3& p_view) const;

  // The view-space point seen at continuous pixel coordinates `pixel` with planar depth
  // `depth_view` (> 0). Exact for any projection whose clip.w does not depend on x, y
  // (every perspective or orthographic camera): solves the 2x2 system of the first two
  // clip rows for x and y at z = -depth_view.
  glm::vec3 view_from_pixel_depth(glm::vec2 pixel, float depth_view) const;

  // Unit view-space direction from the eye through continuous pixel coordinates
  // (for orthographic cameras: -Z).
  glm::vec3 view_ray_direction(glm::vec2 pixel) const;

  // Pixels per scene unit, along x and y, for a length parallel to the image plane at
  // planar depth depth_view. Used to project a world-space radius to the screen. Inline:
  // the kernels call it per pixel in loops over vector lanes.
  glm::vec2 pixels_per_unit(float depth_view) const {
    // clip.w at planar depth d for a point on the axis: w = m[2][3] * (-d) + m[3][3].
    const float w = view_to_clip[2][3] * (-depth_view) + view_to_clip[3][3];
    return {0.5f * float(width_px) * std::abs(view_to_clip[0][0]) / w,
            0.5f * float(height_px) * std::abs(view_to_clip[1][1]) / w};
  }

  glm::vec3 view_from_world_point(const glm::vec3& p_world) const {
    return glm::vec3(world_to_view * glm::vec4(p_world, 1.0f));
  }
  glm::vec3 view_from_world_direction(const glm::vec3& d_world) const {
    return glm::vec3(world_to_view * glm::vec4(d_world, 0.0f));
  }
  glm::vec3 world_from_view_direction(const glm::vec3& d_view) const {
    return glm::vec3(view_to_world * glm::vec4(d_view, 0.0f));
  }
};

// Camera::view_from_pixel_depth's solve over float (ScalarOps); the kernels include the same
// file into each SIMD target's namespace for vectors of pixels (kernels/position_lanes.h).
#include "core/pixel_depth_solve-inl.h"

// The operations of float for PixelDepthSolve.
struct ScalarOps {
  using T = float;
  static float Set(float v) { return v; }
  static float Add(float a, float b) { return a + b; }
  static float Sub(float a, float b) { return a - b; }
  static float Mul(float a, float b) { return a * b; }
  static float Div(float a, float b) { return a / b; }
  static float Neg(float a) { return -a; }
};

// A camera's pixel rays parametrised by planar depth s: the view-space point through pixel
// coordinates (px, py) at depth s is o(px, py) + s u(px, py), u.z = -1 (perspective: o = 0
// exactly and u the point at depth 1; orthographic: o the point at depth 0, u = (0, 0, -1)).
// Both are affine in (px, py): view_from_pixel_depth solves a linear system whose matrix
// does not depend on the pixel for projections whose clip w depends on z only (pinhole and
// orthographic cameras). Kernels walking many pixels' rays use it in place of a solve per
// pixel.
struct PixelRays {
  glm::vec3 o0, ox, oy;  // o(px, py) = o0 + px ox + py oy
  glm::vec3 u0, ux, uy;  // u(px, py) = u0 + px ux + py uy
  glm::vec3 origin(float px, float py) const { return o0 + px * ox + py * oy; }
  glm::vec3 direction(float px, float py) const { return u0 + px * ux + py * uy; }
  glm::vec3 point(float px, float py, float depth) const { return origin(px, py) + depth * direction(px, py); }
};

PixelRays pixel_rays(const Camera& camera);

}  // namespace ssdo
