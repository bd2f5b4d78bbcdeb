#include "kernels/normals.h"

#include <cmath>

#include "core/parallel.h"

namespace ssdo {

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

}  // namespace

void reconstruct_normals_from_depth(const cv::Mat& depth_view, const cv::Mat& mask,
                                    const Camera& camera, cv::Mat& normal_view, cv::Rect roi,
                                    int nthreads) {
  CV_Assert(depth_view.type() == CV_32FC1 && mask.type() == CV_8UC1 &&
            mask.size() == depth_view.size());
  if (normal_view.size() != depth_view.size() || normal_view.type() != CV_32FC3)
    normal_view.create(depth_view.size(), CV_32FC3);
  const cv::Rect r = resolve_roi(roi, depth_view.size());
  const int width = depth_view.cols, height = depth_view.rows;
  const bool perspective = camera.is_perspective();
  // 1/depth is affine in screen space over a plane seen in perspective; depth itself is,
  // orthographically. Masked taps are never read (background depth is +inf).
  auto screen_affine = [perspective](float d) { return perspective ? 1.0f / d : d; };
  // view_from_pixel_depth(pixel, d) = origin(pixel) + d * ray(pixel), both affine in the
  // pixel coordinates for every projection whose clip.w does not depend on x and y (the
  // camera's own assumption): precomputed once, stepped per pixel instead of solving the
  // 2x2 system for each of the up to five taps.
  struct Affine {
    glm::vec3 base, dx, dy;
    glm::vec3 at(int x, int y) const { return base + float(x) * dx + float(y) * dy; }
  };
  auto affine_at_depth = [&](float d) {
    const glm::vec3 b = camera.view_from_pixel_depth({0.5f, 0.5f}, d);
    return Affine{b, camera.view_from_pixel_depth({1.5f, 0.5f}, d) - b,
                  camera.view_from_pixel_depth({0.5f, 1.5f}, d) - b};
  };
  const Affine origin = affine_at_depth(0.0f);
  const Affine at_one = affine_at_depth(1.0f);
  const Affine ray{at_one.base - origin.base, at_one.dx - origin.dx, at_one.dy - origin.dy};
  auto position = [&](int x, int y) {
    return origin.at(x, y) + depth_view.ptr<float>(y)[x] * ray.at(x, y);
  };

  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* depth_row = depth_view.ptr<float>(y);
      // Rows y-2 .. y+2 (nullptr outside the image).
      const uint8_t* mask_rows[5];
      const float* depth_rows[5];
      for (int k = 0; k < 5; ++k) {
        const int yy = y + k - 2;
        const bool inside = yy >= 0 && yy < height;
        mask_rows[k] = inside ? mask.ptr<uint8_t>(yy) : nullptr;
        depth_rows[k] = inside ? depth_view.ptr<float>(yy) : nullptr;
      }
      cv::Vec3f* out = normal_view.ptr<cv::Vec3f>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!m[x]) {
          out[x] = cv::Vec3f(0, 0, 0);
          continue;
        }
        float qx[5], qy[5];
        bool vx[5], vy[5];
        for (int k = 0; k < 5; ++k) {
          const int xx = x + k - 2;
          vx[k] = xx >= 0 && xx < width && m[xx] != 0;
          qx[k] = vx[k] ? screen_affine(depth_row[xx]) : 0.0f;
          vy[k] = mask_rows[k] != nullptr && mask_rows[k][x] != 0;
          qy[k] = vy[k] ? screen_affine(depth_rows[k][x]) : 0.0f;
        }
        const Side side_x = choose_side(qx, vx);
        const Side side_y = choose_side(qy, vy);
        const glm::vec3 p = position(x, y);
        const glm::vec3 eye_ray =
            perspective ? glm::normalize(p) : glm::vec3(0.0f, 0.0f, -1.0f);
        glm::vec3 n = -eye_ray;
        if (side_x != kNone && side_y != kNone) {
          // Tangents oriented along the +x and +y pixel directions (+y = down the image).
          const glm::vec3 t_x = side_x == kCentral
                                    ? position(x + 1, y) - position(x - 1, y)
                                    : float(side_x) * (position(x + side_x, y) - p);
          const glm::vec3 t_y = side_y == kCentral
                                    ? position(x, y + 1) - position(x, y - 1)
                                    : float(side_y) * (position(x, y + side_y) - p);
          const glm::vec3 c = glm::cross(t_y, t_x);
          const float len = glm::length(c);
          if (len > 0.0f && std::isfinite(len)) n = c / len;
        }
        if (glm::dot(n, eye_ray) > 0.0f) n = -n;  // face the camera
        out[x] = cv::Vec3f(n.x, n.y, n.z);
      }
    }
  });
}

}  // namespace ssdo
