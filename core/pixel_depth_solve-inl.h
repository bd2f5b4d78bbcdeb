// Camera::view_from_pixel_depth's solve, and the pixel-to-NDC step it starts with, written
// once for any arithmetic, included into the namespace that uses it (no include guard, no
// includes: Camera and glm come from the includer): once in core/camera.h for float, and once
// per SIMD target inside that target's namespace (kernels/position_lanes.h), so that its
// vector code is compiled with the target's instruction set (a template takes the attributes
// of where it is defined).
//
// Ops names the number type (Ops::T: float, or a vector of floats with one pixel per lane)
// and its operations (Set, Add, Sub, Mul, Div, Neg). Every instance runs the same operations
// in the same order, and the build fuses no multiply-adds (-ffp-contract=off), so a vector of
// pixels gets the bits of the scalar solve pixel by pixel.

// Continuous pixel coordinates to NDC (core/camera.h's convention): ndc_x = 2 px / W - 1,
// ndc_y = 1 - 2 py / H. Camera::ndc_from_pixel is its float instance.
template <class Ops>
void NdcFromPixel(typename Ops::T px, typename Ops::T py, typename Ops::T width_px,
                  typename Ops::T height_px, typename Ops::T& ndc_x, typename Ops::T& ndc_y) {
  using T = typename Ops::T;
  const T one = Ops::Set(1.0f), two = Ops::Set(2.0f);
  ndc_x = Ops::Sub(Ops::Div(Ops::Mul(two, px), width_px), one);
  ndc_y = Ops::Sub(one, Ops::Div(Ops::Mul(two, py), height_px));
}

template <class Ops>
struct PixelDepthSolve {
  using T = typename Ops::T;
  T width_px, height_px;
  T m00, m01, m03, m10, m11, m13, m20, m21, m23, m30, m31, m33;  // view_to_clip[col][row]

  explicit PixelDepthSolve(const Camera& camera) {
    const glm::mat4& m = camera.view_to_clip;
    width_px = Ops::Set(float(camera.width_px)), height_px = Ops::Set(float(camera.height_px));
    m00 = Ops::Set(m[0][0]), m01 = Ops::Set(m[0][1]), m03 = Ops::Set(m[0][3]);
    m10 = Ops::Set(m[1][0]), m11 = Ops::Set(m[1][1]), m13 = Ops::Set(m[1][3]);
    m20 = Ops::Set(m[2][0]), m21 = Ops::Set(m[2][1]), m23 = Ops::Set(m[2][3]);
    m30 = Ops::Set(m[3][0]), m31 = Ops::Set(m[3][1]), m33 = Ops::Set(m[3][3]);
  }

  // The view-space point (x, y, z) at continuous pixel coordinates (px, py) and planar depth
  // depth_view. Row r of the projection: clip_r = m[0][r] x + m[1][r] y + m[2][r] z + m[3][r];
  // ndc_r clip_w = clip_r for r = 0, 1 is the 2x2 system A [x y]^T = b, solved by Cramer's rule.
  void operator()(T px, T py, T depth_view, T& x, T& y, T& z) const {
    T ndc_x, ndc_y;
    NdcFromPixel<Ops>(px, py, width_px, height_px, ndc_x, ndc_y);
    z = Ops::Neg(depth_view);
    const T a00 = Ops::Sub(m00, Ops::Mul(ndc_x, m03)), a01 = Ops::Sub(m10, Ops::Mul(ndc_x, m13));
    const T a10 = Ops::Sub(m01, Ops::Mul(ndc_y, m03)), a11 = Ops::Sub(m11, Ops::Mul(ndc_y, m13));
    const T w = Ops::Add(Ops::Mul(m23, z), m33);  // clip.w at the planar depth
    const T b0 = Ops::Sub(Ops::Mul(ndc_x, w), Ops::Add(Ops::Mul(m20, z), m30));
    const T b1 = Ops::Sub(Ops::Mul(ndc_y, w), Ops::Add(Ops::Mul(m21, z), m31));
    const T det = Ops::Sub(Ops::Mul(a00, a11), Ops::Mul(a01, a10));
    x = Ops::Div(Ops::Sub(Ops::Mul(b0, a11), Ops::Mul(a01, b1)), det);
    y = Ops::Div(Ops::Sub(Ops::Mul(a00, b1), Ops::Mul(b0, a10)), det);
  }
};
