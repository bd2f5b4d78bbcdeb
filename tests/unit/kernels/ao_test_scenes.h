// Shared fixtures of the AO method tests (ao_hemisphere_test, ao_hbao_test, ao_gtao_test):
// synthetic G-buffers from the reference ray caster, pixel sets where closed forms hold,
// and the invariants every method must keep (thread count, range, background, roi).
#pragma once

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "kernels/half_resolution.h"
#include "kernels/ao.h"
#include "tests/support/raycast.h"

namespace ssdo::ao_test {

struct Frame {
  GBuffer g;
  cv::Mat position_world;  // CV_32FC3 world-space points (0 on background)
  AoInputs inputs() const {
    return AoInputs{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera,
                    g.albedo.empty() ? nullptr : &g.albedo};
  }
};

inline Frame render(const raycast::Scene& scene, const Camera& camera) {
  Frame f;
  f.g = raycast::render_gbuffer(scene, camera, 0);
  f.position_world = cv::Mat::zeros(f.g.depth_view.size(), CV_32FC3);
  for (int y = 0; y < f.g.depth_view.rows; ++y)
    for (int x = 0; x < f.g.depth_view.cols; ++x) {
      if (!f.g.mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f p = f.g.position_view.at<cv::Vec3f>(y, x);
      const glm::vec3 w = glm::vec3(camera.view_to_world * glm::vec4(p[0], p[1], p[2], 1.0f));
      f.position_world.at<cv::Vec3f>(y, x) = cv::Vec3f(w.x, w.y, w.z);
    }
  return f;
}

inline AoOutput run(const Frame& f, const AoSettings& s, int nthreads = 0, cv::Rect roi = {}) {
  AoOutput out;
  compute_ao_at_resolution(f.inputs(), s, out, roi, nthreads);
  return out;
}

// "Unlimited" radius: larger than every distance in the test scenes' views; the pixel
// bound is the frame width, so the taps span the frame (further taps would be off screen).
inline AoSettings unlimited(AoMethod method, Preset preset, int frame_width_px) {
  AoSettings s = ao_preset(method, preset);
  s.radius_world = 1000.0f;
  s.max_radius_px = float(frame_width_px);
  return s;
}

struct Pixel {
  int x, y;
};

template <class Pred>
std::vector<Pixel> select(const Frame& f, Pred pred) {
  std::vector<Pixel> out;
  for (int y = 0; y < f.g.depth_view.rows; ++y)
    for (int x = 0; x < f.g.depth_view.cols; ++x) {
      if (!f.g.mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f p = f.position_world.at<cv::Vec3f>(y, x);
      if (pred(glm::vec3(p[0], p[1], p[2]), x, y)) out.push_back({x, y});
    }
  return out;
}

inline double mean_at(const cv::Mat& ao, const std::vector<Pixel>& px) {
  double sum = 0.0;
  for (const Pixel& p : px) sum += ao.at<float>(p.y, p.x);
  return px.empty() ? NAN : sum / double(px.size());
}

inline double max_abs_dev(const cv::Mat& ao, const std::vector<Pixel>& px, double expected) {
  double m = 0.0;
  for (const Pixel& p : px) m = std::max(m, std::abs(double(ao.at<float>(p.y, p.x)) - expected));
  return m;
}

// Floor pixels (z ~ 0) with 0.02 < x < 0.06 from the wall x = 0, away from the frame's
// near and far ends (|y| < 0.6): the corner line of corner_scene, AO = 0.5 unlimited.
inline std::vector<Pixel> corner_line_pixels(const Frame& f) {
  return select(f, [](glm::vec3 p, int, int) {
    return std::abs(p.z) < 1e-3f && p.x > 0.02f && p.x < 0.06f && std::abs(p.y) < 0.6f;
  });
}

// corner_scene's floor within a radius R of the wall: the pixels from 0.02 to R / 2 from it,
// away from the frame's near and far ends, and the mean over them of the closed form
// 1 - (acos(a) - a sqrt(1 - a^2)) / pi, a = d / R at distance d from the wall (raycast.h).
struct CornerFloor {
  std::vector<Pixel> pixels;
  double exact = 0.0;
};
inline CornerFloor corner_floor(const Frame& f, float radius_world) {
  CornerFloor c;
  c.pixels = select(f, [radius_world](glm::vec3 p, int, int) {
    return std::abs(p.z) < 1e-3f && p.x > 0.02f && p.x < 0.5f * radius_world && std::abs(p.y) < 0.3f;
  });
  for (const Pixel& px : c.pixels) {
    const double a = std::min(1.0, double(f.position_world.at<cv::Vec3f>(px.y, px.x)[0]) / radius_world);
    c.exact += 1.0 - (std::acos(a) - a * std::sqrt(1.0 - a * a)) / std::numbers::pi;
  }
  if (!c.pixels.empty()) c.exact /= double(c.pixels.size());
  return c;
}

// Floor pixels within `r` of the foot point (0, 0, 0) under the sphere.
inline std::vector<Pixel> foot_pixels(const Frame& f, float r) {
  return select(f, [r](glm::vec3 p, int, int) {
    return std::abs(p.z) < 1e-3f && std::hypot(p.x, p.y) < r;
  });
}

inline std::vector<Pixel> all_pixels(const Frame& f) {
  return select(f, [](glm::vec3, int, int) { return true; });
}

// Invariants of every method: bitwise identical for 1 and 2 threads, AO in [0, 1],
// 1 on background, roi-only writes.
inline void check_invariants(AoMethod method, Preset preset,
                             float thickness_world = std::numeric_limits<float>::infinity()) {
  const Frame f = render(raycast::sphere_over_plane(0.5f, 1.5f),
                         raycast::sphere_over_plane_camera(0.5f, 1.5f, 96, 64));
  // Some background: look a little upwards too.
  AoSettings s = ao_preset(method, preset);
  s.radius_world = 2.0f;
  s.thickness_world = thickness_world;
  const AoOutput a = run(f, s, 1), b = run(f, s, 2);
  ASSERT_EQ(a.ao.type(), CV_32FC1);
  EXPECT_EQ(cv::norm(a.ao, b.ao, cv::NORM_INF), 0.0);
  EXPECT_EQ(0, std::memcmp(a.ao.data, b.ao.data, a.ao.total() * a.ao.elemSize()));
  if (!a.bent_normal_view.empty()) {
    EXPECT_EQ(0, std::memcmp(a.bent_normal_view.data, b.bent_normal_view.data,
                             a.bent_normal_view.total() * a.bent_normal_view.elemSize()));
  }
  double lo, hi;
  cv::minMaxLoc(a.ao, &lo, &hi);
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 1.0);
  EXPECT_LT(lo, 0.9);  // the sphere and floor do occlude somewhere
  int background = 0;
  for (int y = 0; y < f.g.mask.rows; ++y)
    for (int x = 0; x < f.g.mask.cols; ++x)
      if (!f.g.mask.at<uint8_t>(y, x)) {
        ++background;
        EXPECT_EQ(a.ao.at<float>(y, x), 1.0f);
      }
  EXPECT_GT(background, 0);
  // roi: outside untouched, inside equal to the full-frame result.
  AoOutput r;
  r.ao = cv::Mat(f.g.depth_view.size(), CV_32FC1, cv::Scalar(-7.0f));
  if (method != AoMethod::hemisphere)
    r.bent_normal_view = cv::Mat(f.g.depth_view.size(), CV_32FC3, cv::Scalar::all(-7.0f));
  const cv::Rect roi(13, 9, 40, 31);
  compute_ao_at_resolution(f.inputs(), s, r, roi, 2);
  for (int y = 0; y < r.ao.rows; ++y)
    for (int x = 0; x < r.ao.cols; ++x) {
      if (roi.contains({x, y})) {
        EXPECT_EQ(r.ao.at<float>(y, x), a.ao.at<float>(y, x));
      } else {
        EXPECT_EQ(r.ao.at<float>(y, x), -7.0f);
      }
    }
  if (method != AoMethod::hemisphere) {
    EXPECT_EQ(r.bent_normal_view.at<cv::Vec3f>(0, 0), cv::Vec3f::all(-7.0f));
    const cv::Vec3f bn = r.bent_normal_view.at<cv::Vec3f>(roi.y + 5, roi.x + 5);
    if (f.g.mask.at<uint8_t>(roi.y + 5, roi.x + 5)) {
      EXPECT_NEAR(cv::norm(bn), 1.0, 1e-4);
    }
  }
}

}  // namespace ssdo::ao_test
