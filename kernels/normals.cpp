#include "kernels/normals.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/normals.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <cmath>

#include "core/parallel.h"
#include "kernels/positions.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

namespace {

// What a pixel's tangent along one axis is built from.
enum Side { kNone = 0, kPrevious = -1, kNext = +1, kCentral = 2 };

// Chooses the difference for pixel `c` along one axis. q[k] is the screen-affine depth
// quantity at offset k - 2, valid[k] says whether that tap is in the image and in the mask.
Side choose_side(const float q[5], const bool valid[5]) {
  const bool prev1 = valid[1], next1 = valid[3];
  if (!prev1 && !next1) return kNone;
  if (!prev1) return kNext;
  if (!next1) return kPrevious;
  if (valid[0] && valid[4]) {
    const float err_prev = std::abs(2.0f * q[1] - q[0] - q[2]);
    const float err_next = std::abs(2.0f * q[3] - q[4] - q[2]);
    // Both sides continue the surface equally well (a plane, or a smooth curved surface
    // whose two extrapolation errors are both curvature terms of similar size): the
    // central difference is second-order accurate there. Across a depth edge or a crease
    // one error is far larger than the other and the one-sided difference on the good
    // side is taken. kRoundoff covers float rounding of q on planes (errors ~1e-7 q).
    constexpr float kAgreement = 2.0f;
    const float roundoff = 1e-5f * std::abs(q[2]);
    if (err_prev <= kAgreement * err_next + roundoff && err_next <= kAgreement * err_prev + roundoff)
      return kCentral;
    return err_next <= err_prev ? kNext : kPrevious;
  }
  return std::abs(q[3] - q[2]) <= std::abs(q[1] - q[2]) ? kNext : kPrevious;
}

// view_from_pixel_depth(pixel, d) = origin(pixel) + d * ray(pixel), both affine in the
// pixel coordinates for every projection whose clip.w does not depend on x and y (the
// camera's own assumption): precomputed once, stepped per pixel instead of solving the 2x2
// system for each of the up to five taps.
struct Affine {
  glm::vec3 base, dx, dy;
  glm::vec3 at(int x, int y) const { return base + float(x) * dx + float(y) * dy; }
};

Affine affine_at_depth(const Camera& camera, float d) {
  const glm::vec3 b = camera.view_from_pixel_depth({0.5f, 0.5f}, d);
  return Affine{b, camera.view_from_pixel_depth({1.5f, 0.5f}, d) - b,
                camera.view_from_pixel_depth({0.5f, 1.5f}, d) - b};
}

// What every pixel reads: the depth and mask, and the camera as the affine position map.
struct NormalFrame {
  const cv::Mat& depth_view;
  const cv::Mat& mask;
  int width, height;
  bool perspective;
  Affine origin, ray;

  NormalFrame(const cv::Mat& depth, const cv::Mat& m, const Camera& camera)
      : depth_view(depth), mask(m), width(depth.cols), height(depth.rows),
        perspective(camera.is_perspective()), origin(affine_at_depth(camera, 0.0f)) {
    const Affine at_one = affine_at_depth(camera, 1.0f);
    ray = Affine{at_one.base - origin.base, at_one.dx - origin.dx, at_one.dy - origin.dy};
  }
  // 1/depth is affine in screen space over a plane seen in perspective; depth itself is,
  // orthographically. Masked taps are never read (background depth is +inf).
  float screen_affine(float d) const { return perspective ? 1.0f / d : d; }
  glm::vec3 position(int x, int y) const {
    return origin.at(x, y) + depth_view.ptr<float>(y)[x] * ray.at(x, y);
  }
};

// The rows a pixel's vertical taps read: y - 2 .. y + 2 (null outside the image).
struct RowWindow {
  const uint8_t* mask_rows[5];
  const float* depth_rows[5];
};

RowWindow row_window(const NormalFrame& f, int y) {
  RowWindow w;
  for (int k = 0; k < 5; ++k) {
    const int yy = y + k - 2;
    const bool inside = yy >= 0 && yy < f.height;
    w.mask_rows[k] = inside ? f.mask.ptr<uint8_t>(yy) : nullptr;
    w.depth_rows[k] = inside ? f.depth_view.ptr<float>(yy) : nullptr;
  }
  return w;
}

// The unit normal of foreground pixel (x, y), facing the camera (method in normals.h).
glm::vec3 normal_at(const NormalFrame& f, const RowWindow& w, int x, int y) {
  const uint8_t* m = w.mask_rows[2];
  const float* depth_row = w.depth_rows[2];
  float qx[5], qy[5];
  bool vx[5], vy[5];
  for (int k = 0; k < 5; ++k) {
    const int xx = x + k - 2;
    vx[k] = xx >= 0 && xx < f.width && m[xx] != 0;
    qx[k] = vx[k] ? f.screen_affine(depth_row[xx]) : 0.0f;
    vy[k] = w.mask_rows[k] != nullptr && w.mask_rows[k][x] != 0;
    qy[k] = vy[k] ? f.screen_affine(w.depth_rows[k][x]) : 0.0f;
  }
  const Side side_x = choose_side(qx, vx);
  const Side side_y = choose_side(qy, vy);
  const glm::vec3 p = f.position(x, y);
  const glm::vec3 eye_ray = f.perspective ? glm::normalize(p) : glm::vec3(0.0f, 0.0f, -1.0f);
  glm::vec3 n = -eye_ray;
  if (side_x != kNone && side_y != kNone) {
    // Tangents oriented along the +x and +y pixel directions (+y = down the image).
    const glm::vec3 t_x = side_x == kCentral ? f.position(x + 1, y) - f.position(x - 1, y)
                                             : float(side_x) * (f.position(x + side_x, y) - p);
    const glm::vec3 t_y = side_y == kCentral ? f.position(x, y + 1) - f.position(x, y - 1)
                                             : float(side_y) * (f.position(x, y + side_y) - p);
    const glm::vec3 c = glm::cross(t_y, t_x);
    const float len = glm::length(c);
    if (len > 0.0f && std::isfinite(len)) n = c / len;
  }
  if (glm::dot(n, eye_ray) > 0.0f) n = -n;  // face the camera
  return n;
}

}  // namespace

void reconstruct_normals_from_depth(const cv::Mat& depth_view, const cv::Mat& mask,
                                    const Camera& camera, cv::Mat& normal_view, cv::Rect roi,
                                    int nthreads) {
  const cv::Rect r = prepare_view_vectors(depth_view, mask, normal_view, roi);
  const NormalFrame frame(depth_view, mask, camera);
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const RowWindow window = row_window(frame, y);
      const uint8_t* m = window.mask_rows[2];
      cv::Vec3f* out = normal_view.ptr<cv::Vec3f>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!m[x]) {
          out[x] = cv::Vec3f(0, 0, 0);
          continue;
        }
        const glm::vec3 n = normal_at(frame, window, x, y);
        out[x] = cv::Vec3f(n.x, n.y, n.z);
      }
    }
  });
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(reconstruct_normals_from_depth);
void reconstruct_normals_from_depth(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                                    cv::Mat& normal_view, cv::Rect roi, int nthreads) {
  HWY_DYNAMIC_DISPATCH(reconstruct_normals_from_depth)(depth_view, mask, camera, normal_view, roi, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
