// Points of pixel rays and their projection into a camera, a vector of pixels at a time
// (Highway): the lane form of core/camera.h's PixelRays::point and Camera::pixel_from_view,
// for the kernels that carry many pixels from one frame into another (kernels/temporal.cpp,
// kernels/temporal_change.cpp).
//
// Included once per instruction set (by the kernels' foreach_target files, after
// hwy/highway.h), into that target's namespace, as kernels/integer_power.h.
#if defined(SSDO_KERNELS_REPROJECTION_LANES_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef SSDO_KERNELS_REPROJECTION_LANES_H_
#undef SSDO_KERNELS_REPROJECTION_LANES_H_
#else
#define SSDO_KERNELS_REPROJECTION_LANES_H_
#endif

#include <glm/glm.hpp>
#include <hwy/highway.h>

#include "core/camera.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace reprojection_lanes {

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
using VF = hn::Vec<DF>;
using MF = hn::Mask<DF>;

// Three lanes' worth of vectors: points, normals, rows of a matrix.
struct Vec3L {
  VF x, y, z;
};
inline Vec3L broadcast(const glm::vec3& v) {
  const DF d;
  return {hn::Set(d, v.x), hn::Set(d, v.y), hn::Set(d, v.z)};
}
inline VF dot(const Vec3L& a, const Vec3L& b) {
  return hn::Add(hn::Add(hn::Mul(a.x, b.x), hn::Mul(a.y, b.y)), hn::Mul(a.z, b.z));
}
// a + s b, per component.
inline Vec3L add_scaled(const Vec3L& a, VF s, const Vec3L& b) {
  return {hn::Add(a.x, hn::Mul(s, b.x)), hn::Add(a.y, hn::Mul(s, b.y)), hn::Add(a.z, hn::Mul(s, b.z))};
}
inline Vec3L sub(const Vec3L& a, const Vec3L& b) { return {hn::Sub(a.x, b.x), hn::Sub(a.y, b.y), hn::Sub(a.z, b.z)}; }

// The point at pixel coordinates (px, py) and planar depth d of pixel rays (core/camera.h).
inline Vec3L ray_point(const PixelRays& r, VF px, VF py, VF d) {
  const Vec3L origin = add_scaled(add_scaled(broadcast(r.o0), px, broadcast(r.ox)), py, broadcast(r.oy));
  const Vec3L direction = add_scaled(add_scaled(broadcast(r.u0), px, broadcast(r.ux)), py, broadcast(r.uy));
  return add_scaled(origin, d, direction);
}

// Camera::pixel_from_view of view-space points p of `camera`: their continuous pixel
// coordinates; `valid` where clip.w > 0 (in front of the eye; elsewhere the coordinates are
// those of clip.w = 1, not NaN: use them only under `valid`).
struct ProjectedLanes {
  VF pixel_x, pixel_y;
  MF valid;
};
inline ProjectedLanes project(const Camera& camera, const Vec3L& p) {
  const DF d;
  const glm::mat4& m = camera.view_to_clip;  // m[column][row]
  auto clip_row = [&](int row) {
    return hn::Add(dot({hn::Set(d, m[0][row]), hn::Set(d, m[1][row]), hn::Set(d, m[2][row])}, p),
                   hn::Set(d, m[3][row]));
  };
  const VF clip_w = clip_row(3);
  const MF valid = hn::Gt(clip_w, hn::Zero(d));
  const VF w = hn::IfThenElse(valid, clip_w, hn::Set(d, 1.0f));
  const VF half = hn::Set(d, 0.5f), one = hn::Set(d, 1.0f);
  return {hn::Mul(hn::Mul(half, hn::Add(hn::Div(clip_row(0), w), one)), hn::Set(d, float(camera.width_px))),
          hn::Mul(hn::Mul(half, hn::Sub(one, hn::Div(clip_row(1), w))), hn::Set(d, float(camera.height_px))), valid};
}

}  // namespace reprojection_lanes
}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_REPROJECTION_LANES_H_
