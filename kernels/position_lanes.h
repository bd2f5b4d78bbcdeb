// Camera::view_from_pixel_depth for a vector of pixels (Highway): its one solve
// (PixelDepthSolve, core/pixel_depth_solve-inl.h) over vectors, for the loops that turn a
// grid's depths into view-space positions.
//
// Included once per instruction set (by the kernels' foreach_target files, after
// hwy/highway.h), into that target's namespace, as kernels/mask_lanes.h.
#if defined(SSDO_KERNELS_POSITION_LANES_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef SSDO_KERNELS_POSITION_LANES_H_
#undef SSDO_KERNELS_POSITION_LANES_H_
#else
#define SSDO_KERNELS_POSITION_LANES_H_
#endif

#include <hwy/highway.h>

#include "core/camera.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

// The camera's solve, compiled for this target (core/pixel_depth_solve-inl.h).
#include "core/pixel_depth_solve-inl.h"

// The operations of this target's float vectors, for PixelDepthSolve: one pixel per lane.
struct LaneOps {
  using D = hwy::HWY_NAMESPACE::ScalableTag<float>;
  using T = hwy::HWY_NAMESPACE::Vec<D>;
  static T Set(float v) { return hwy::HWY_NAMESPACE::Set(D(), v); }
  static T Add(T a, T b) { return hwy::HWY_NAMESPACE::Add(a, b); }
  static T Sub(T a, T b) { return hwy::HWY_NAMESPACE::Sub(a, b); }
  static T Mul(T a, T b) { return hwy::HWY_NAMESPACE::Mul(a, b); }
  static T Div(T a, T b) { return hwy::HWY_NAMESPACE::Div(a, b); }
  static T Neg(T a) { return hwy::HWY_NAMESPACE::Neg(a); }
};

// Camera::view_from_pixel_depth for a vector of pixels, with the bits of the scalar solve.
using PixelDepthLanes = PixelDepthSolve<LaneOps>;

// The loops' scalar tail: the view-space position at pixel coordinates (px, py) and planar
// depth depth_view where `foreground`, else 0, stored as three floats at out.
inline void store_position_or_zero(const Camera& camera, bool foreground, float px, float py, float depth_view,
                                   float* out) {
  const glm::vec3 p = foreground ? camera.view_from_pixel_depth({px, py}, depth_view) : glm::vec3(0.0f);
  out[0] = p.x, out[1] = p.y, out[2] = p.z;
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_POSITION_LANES_H_
