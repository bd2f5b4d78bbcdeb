// Camera::view_from_pixel_depth for a vector of pixels (Highway), for the loops that turn a
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

// The camera's terms of the solve, each in every lane.
struct PixelDepthSolve {
  using D = hwy::HWY_NAMESPACE::ScalableTag<float>;
  using V = hwy::HWY_NAMESPACE::Vec<D>;
  V width_px, height_px;
  V m00, m01, m03, m10, m11, m13, m20, m21, m23, m30, m31, m33;  // m[col][row]

  explicit PixelDepthSolve(const Camera& camera) {
    namespace hn = hwy::HWY_NAMESPACE;
    const D d;
    const glm::mat4& m = camera.view_to_clip;
    width_px = hn::Set(d, float(camera.width_px));
    height_px = hn::Set(d, float(camera.height_px));
    m00 = hn::Set(d, m[0][0]), m01 = hn::Set(d, m[0][1]), m03 = hn::Set(d, m[0][3]);
    m10 = hn::Set(d, m[1][0]), m11 = hn::Set(d, m[1][1]), m13 = hn::Set(d, m[1][3]);
    m20 = hn::Set(d, m[2][0]), m21 = hn::Set(d, m[2][1]), m23 = hn::Set(d, m[2][3]);
    m30 = hn::Set(d, m[3][0]), m31 = hn::Set(d, m[3][1]), m33 = hn::Set(d, m[3][3]);
  }

  // The view-space point (x, y, z) seen at pixel coordinates (px, py) at planar depth
  // depth_view, lane by lane: Camera::view_from_pixel_depth's operations in its order (no
  // fused multiply-adds), so the same bits as the scalar solve.
  void operator()(V px, V py, V depth_view, V& x, V& y, V& z) const {
    namespace hn = hwy::HWY_NAMESPACE;
    const D d;
    const V one = hn::Set(d, 1.0f), two = hn::Set(d, 2.0f);
    const V ndc_x = hn::Sub(hn::Div(hn::Mul(two, px), width_px), one);
    const V ndc_y = hn::Sub(one, hn::Div(hn::Mul(two, py), height_px));
    z = hn::Neg(depth_view);
    const V a00 = hn::Sub(m00, hn::Mul(ndc_x, m03)), a01 = hn::Sub(m10, hn::Mul(ndc_x, m13));
    const V a10 = hn::Sub(m01, hn::Mul(ndc_y, m03)), a11 = hn::Sub(m11, hn::Mul(ndc_y, m13));
    const V w = hn::Add(hn::Mul(m23, z), m33);  // clip.w over the planar depth
    const V b0 = hn::Sub(hn::Mul(ndc_x, w), hn::Add(hn::Mul(m20, z), m30));
    const V b1 = hn::Sub(hn::Mul(ndc_y, w), hn::Add(hn::Mul(m21, z), m31));
    const V det = hn::Sub(hn::Mul(a00, a11), hn::Mul(a01, a10));
    x = hn::Div(hn::Sub(hn::Mul(b0, a11), hn::Mul(a01, b1)), det);
    y = hn::Div(hn::Sub(hn::Mul(a00, b1), hn::Mul(b0, a10)), det);
  }
};

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_POSITION_LANES_H_
