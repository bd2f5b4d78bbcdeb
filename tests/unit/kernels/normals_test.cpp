// reconstruct_normals_from_depth on analytic depth maps: a tilted plane, a sphere, and a
// depth step between two planes (no smearing across the edge).
#include "kernels/normals.h"

#include <cmath>
#include <functional>
#include <limits>
#include <optional>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

constexpr int kWidth = 160, kHeight = 120;

// A depth map and its true normals from a per-pixel ray cast (nullopt = background).
struct Scene {
  Camera camera = Camera::from_fov_x(kWidth, kHeight, 60.0f);
  cv::Mat depth{kHeight, kWidth, CV_32FC1, cv::Scalar(std::numeric_limits<float>::infinity())};
  cv::Mat mask{kHeight, kWidth, CV_8UC1, cv::Scalar(0)};
  cv::Mat truth{kHeight, kWidth, CV_32FC3, cv::Scalar(0, 0, 0)};
};

struct Hit {
  float t;  // along the ray d with d.z = -1, so t is the planar depth
  glm::vec3 normal;
};

Scene render(const std::function<std::optional<Hit>(const glm::vec3& d)>& cast) {
  Scene s;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const glm::vec3 d = s.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, 1.0f);
      if (auto h = cast(d)) {
        s.depth.at<float>(y, x) = h->t;
        s.mask.at<uint8_t>(y, x) = 255;
        s.truth.at<cv::Vec3f>(y, x) = cv::Vec3f(h->normal.x, h->normal.y, h->normal.z);
      }
    }
  return s;
}

std::optional<Hit> plane(const glm::vec3& d, const glm::vec3& n, const glm::vec3& p0) {
  const float t = glm::dot(n, p0) / glm::dot(n, d);
  if (!(t > 0.0f)) return std::nullopt;
  return Hit{t, n};
}

double angle_deg(const cv::Vec3f& a, const cv::Vec3f& b) {
  const double c = std::clamp(double(a.dot(b)) / (cv::norm(a) * cv::norm(b)), -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

// Largest angle between reconstructed and true normals over pixels whose neighbourhood of
// radius `margin` is entirely foreground (and, with `all_pixels`, every foreground pixel).
double max_error(const Scene& s, const cv::Mat& normals, int margin) {
  double worst = 0;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      bool interior = s.mask.at<uint8_t>(y, x) != 0;
      for (int dy = -margin; dy <= margin && interior; ++dy)
        for (int dx = -margin; dx <= margin && interior; ++dx) {
          const int xx = x + dx, yy = y + dy;
          interior = xx >= 0 && yy >= 0 && xx < kWidth && yy < kHeight && s.mask.at<uint8_t>(yy, xx);
        }
      if (interior) worst = std::max(worst, angle_deg(normals.at<cv::Vec3f>(y, x), s.truth.at<cv::Vec3f>(y, x)));
    }
  return worst;
}

TEST(ReconstructNormals, TiltedPlaneIsExact) {
  const glm::vec3 n = glm::normalize(glm::vec3(0.4f, -0.3f, 0.8f));
  const Scene s = render([&](const glm::vec3& d) { return plane(d, n, {0.0f, 0.0f, -5.0f}); });
  cv::Mat normals;
  reconstruct_normals_from_depth(s.depth, s.mask, s.camera, normals);
  EXPECT_LT(max_error(s, normals, 0), 0.05);  // every pixel, borders included
}

TEST(ReconstructNormals, SphereWithinOneDegreeAwayFromTheSilhouette) {
  const glm::vec3 c(0.3f, -0.2f, -6.0f);
  const float radius = 2.0f;
  const Scene s = render([&](const glm::vec3& d) -> std::optional<Hit> {
    // |t d - c|^2 = r^2
    const float a = glm::dot(d, d), b = -2.0f * glm::dot(d, c), k = glm::dot(c, c) - radius * radius;
    const float disc = b * b - 4 * a * k;
    if (disc < 0) return std::nullopt;
    const float t = (-b - std::sqrt(disc)) / (2 * a);
    return Hit{t, glm::normalize(t * d - c)};
  });
  ASSERT_GT(cv::countNonZero(s.mask), 3000);
  cv::Mat normals;
  reconstruct_normals_from_depth(s.depth, s.mask, s.camera, normals);
  // Away from the silhouette: the 5-tap footprint (+-2 px) plus 2 px, where the surface is
  // not yet grazing (measured: 0.15 deg at 4 px, 1.4 deg at 3 px, 2.8 deg at 1 px, where one
  // pixel spans tens of degrees of the sphere).
  EXPECT_LT(max_error(s, normals, 4), 1.0);
  EXPECT_LT(max_error(s, normals, 10), 0.1);
  // Background stays (0, 0, 0); every foreground normal is unit and faces the camera.
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const cv::Vec3f nn = normals.at<cv::Vec3f>(y, x);
      if (!s.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(nn, cv::Vec3f(0, 0, 0));
        continue;
      }
      EXPECT_NEAR(cv::norm(nn), 1.0, 1e-5);
      const glm::vec3 p = s.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, s.depth.at<float>(y, x));
      EXPECT_LT(glm::dot(glm::vec3(nn[0], nn[1], nn[2]), p), 0.0f);
    }
}

TEST(ReconstructNormals, NoSmearingAcrossADepthStep) {
  // Left half: a plane at depth ~3 tilted one way; right half: a plane at depth ~9 tilted
  // the other way. Pixels right next to the step keep their own plane's normal.
  const glm::vec3 n_near = glm::normalize(glm::vec3(0.3f, 0.2f, 1.0f));
  const glm::vec3 n_far = glm::normalize(glm::vec3(-0.5f, 0.1f, 1.0f));
  const Camera cam = Camera::from_fov_x(kWidth, kHeight, 60.0f);
  const Scene s = render([&](const glm::vec3& d) {
    const glm::vec2 px = cam.pixel_from_view(d);
    return px.x < kWidth / 2 ? plane(d, n_near, {0, 0, -3.0f}) : plane(d, n_far, {0, 0, -9.0f});
  });
  cv::Mat normals;
  reconstruct_normals_from_depth(s.depth, s.mask, s.camera, normals);
  double worst = 0;
  for (int y = 0; y < kHeight; ++y)
    for (int x = kWidth / 2 - 3; x < kWidth / 2 + 3; ++x)
      worst = std::max(worst, angle_deg(normals.at<cv::Vec3f>(y, x), s.truth.at<cv::Vec3f>(y, x)));
  EXPECT_LT(worst, 0.05);
  EXPECT_LT(max_error(s, normals, 0), 0.05);
}

TEST(ReconstructNormals, StepAgainstBackgroundAndIsolatedPixels) {
  // A single foreground pixel has no neighbours: it faces the eye.
  const Camera cam = Camera::from_fov_x(8, 8, 60.0f);
  cv::Mat depth(8, 8, CV_32FC1, cv::Scalar(std::numeric_limits<float>::infinity()));
  cv::Mat mask(8, 8, CV_8UC1, cv::Scalar(0));
  depth.at<float>(2, 5) = 4.0f;
  mask.at<uint8_t>(2, 5) = 255;
  cv::Mat normals;
  reconstruct_normals_from_depth(depth, mask, cam, normals);
  const glm::vec3 ray = glm::normalize(cam.view_from_pixel_depth({5.5f, 2.5f}, 1.0f));
  const cv::Vec3f n = normals.at<cv::Vec3f>(2, 5);
  EXPECT_NEAR(n[0], -ray.x, 1e-6);
  EXPECT_NEAR(n[1], -ray.y, 1e-6);
  EXPECT_NEAR(n[2], -ray.z, 1e-6);
}

TEST(ReconstructNormals, RoiOnlyAndSameBytesForAnyThreadCount) {
  const glm::vec3 c(0.0f, 0.0f, -5.0f);
  const Scene s = render([&](const glm::vec3& d) -> std::optional<Hit> {
    const float a = glm::dot(d, d), b = -2.0f * glm::dot(d, c), k = glm::dot(c, c) - 4.0f;
    const float disc = b * b - 4 * a * k;
    if (disc < 0) return plane(d, {0, 0, 1}, {0, 0, -12.0f});
    const float t = (-b - std::sqrt(disc)) / (2 * a);
    return Hit{t, glm::normalize(t * d - c)};
  });
  cv::Mat one, many;
  reconstruct_normals_from_depth(s.depth, s.mask, s.camera, one, {}, 1);
  reconstruct_normals_from_depth(s.depth, s.mask, s.camera, many, {}, 4);
  EXPECT_EQ(cv::norm(one, many, cv::NORM_INF), 0.0);
  cv::Mat roi(kHeight, kWidth, CV_32FC3, cv::Scalar(7, 7, 7));
  const cv::Rect r(10, 20, 30, 40);
  reconstruct_normals_from_depth(s.depth, s.mask, s.camera, roi, r, 2);
  EXPECT_EQ(cv::norm(roi(r), one(r), cv::NORM_INF), 0.0);
  EXPECT_EQ(roi.at<cv::Vec3f>(0, 0), cv::Vec3f(7, 7, 7));
  EXPECT_EQ(roi.at<cv::Vec3f>(20, 40), cv::Vec3f(7, 7, 7));
}

}  // namespace
}  // namespace ssdo
