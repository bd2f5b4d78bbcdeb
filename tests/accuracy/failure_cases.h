// The failure-case suite of the screen-space estimators: synthetic frames from the
// reference ray caster (tests/support/raycast.h) where screen-space AO is known to fail, each
// with its ray-traced reference, and the measurements the suite reports (MAE, max error,
// temporal flicker). Shared by tests/accuracy/failure_cases_test.cpp (thresholds) and
// tests/bench/failure_strips.cpp (the table and image strips of docs/accuracy.md).
//
// Every frame is 160x90 (the ray caster's test size), AO radius 1 scene unit (the Cycles
// default), reference: 256 cosine-weighted rays per pixel within the radius (MC noise of
// the reference: standard deviation <= 0.5 / sqrt(256) = 0.031 per pixel, less with the
// R2 sequence's stratification).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kernels/half_resolution.h"
#include "kernels/ao.h"
#include "kernels/confidence.h"
#include "kernels/noise.h"
#include "kernels/normals.h"
#include "kernels/positions.h"
#include "tests/support/raycast.h"

namespace ssdo::failure {

inline constexpr int kWidth = 160, kHeight = 90;
inline constexpr float kRadius = 1.0f;
inline constexpr int kReferenceRays = 256;
inline constexpr uint32_t kReferenceSeed = 7;
inline constexpr float kInf = std::numeric_limits<float>::infinity();

// One frame of a case: the input as the estimator sees it (possibly degraded), the clean
// geometry's reference and the pixels compared.
struct Frame {
  GBuffer input;       // depth, mask, normals, positions (recomputed from depth), albedo;
                       // depth_back_view = the back-face pass (used only when asked)
  cv::Mat reference;   // CV_32FC1 ray-traced AO of the clean frame, 1 on background
  cv::Mat eval_mask;   // CV_8UC1: pixels compared (foreground of the clean frame, minus
                       // pixels the degradation removed)
  cv::Mat position_world;  // CV_32FC3 clean world-space points (0 on background)
};

struct Case {
  std::string name;     // short id: thin, floating, edges, grazing, half, unorm16, ...
  std::string title;    // for the table of docs/accuracy.md
  std::vector<Frame> frames;  // 1, or 8 for the camera pan
  raycast::Scene scene;
};

inline cv::Mat world_positions(const GBuffer& g) {
  cv::Mat w = cv::Mat::zeros(g.depth_view.size(), CV_32FC3);
  for (int y = 0; y < w.rows; ++y)
    for (int x = 0; x < w.cols; ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f p = g.position_view.at<cv::Vec3f>(y, x);
      const glm::vec3 q = glm::vec3(g.camera.view_to_world * glm::vec4(p[0], p[1], p[2], 1.0f));
      w.at<cv::Vec3f>(y, x) = cv::Vec3f(q.x, q.y, q.z);
    }
  return w;
}

inline Frame clean_frame(const raycast::Scene& scene, const Camera& camera) {
  Frame f;
  f.input = raycast::render_gbuffer(scene, camera, 0);
  f.input.depth_back_view = raycast::render_depth_back(scene, camera, 0);
  f.reference = raycast::reference_ao(scene, f.input, kRadius, kReferenceRays, kReferenceSeed, 0);
  f.eval_mask = f.input.mask.clone();
  f.position_world = world_positions(f.input);
  return f;
}

// Positions from the (degraded) depth, as the pipeline does for a frame without them.
inline void recompute_positions(GBuffer& g) {
  g.position_view.release();
  view_positions_from_depth(g.depth_view, g.mask, g.camera, g.position_view, {}, 0);
}

// ---------------------------------------------------------------------------------------
// Scenes of the cases that the ray caster's builders do not have.

// poles_scene plus a thin plate (0.8 x 0.02 x 0.6) 0.4 in front of the wall.
inline raycast::Scene thin_scene() {
  raycast::Scene s = raycast::poles_scene();
  raycast::Box plate;
  plate.centre_world = {-0.9f, 2.6f, 1.5f};
  plate.half_extents_world = {0.4f, 0.01f, 0.3f};
  s.boxes.push_back(plate);
  return s;
}

// Depth discontinuities at the scale of the radius: a sphere, a tilted box and a tall thin
// box floating 0.35-0.8 units in front of a back plane y = 3 (no floor). floating_scene's
// gaps (4-6 units) are beyond a radius of 1, where every method's radius cut already
// removes the halo; here the gap is inside the radius, where a height field darkens the
// back plane around every silhouette and a finite thickness guesses.
inline raycast::Scene floating_near_scene() {
  raycast::Scene s;
  s.planes.push_back({glm::vec3(0.0f, 3.0f, 0.0f), glm::vec3(0.0f, -1.0f, 0.0f), glm::vec3(0.8f)});
  s.spheres.push_back({glm::vec3(0.2f, 3.0f - 0.35f - 0.5f, 1.0f), 0.5f, glm::vec3(0.8f)});
  raycast::Box tilted;
  tilted.centre_world = {-1.3f, 3.0f - 0.6f - 0.35f, 1.1f};
  tilted.half_extents_world = {0.3f, 0.3f, 0.3f};
  const float a = glm::radians(30.0f);
  tilted.rotation = glm::mat3(glm::vec3(std::cos(a), std::sin(a), 0.0f),
                              glm::vec3(-std::sin(a), std::cos(a), 0.0f), glm::vec3(0, 0, 1));
  s.boxes.push_back(tilted);
  raycast::Box pole;
  pole.centre_world = {1.4f, 3.0f - 0.8f - 0.15f, 1.0f};
  pole.half_extents_world = {0.15f, 0.15f, 1.6f};
  s.boxes.push_back(pole);
  return s;
}
inline Camera floating_near_camera() {
  return raycast::look_at({0.0f, -1.5f, 1.0f}, {0.0f, 3.0f, 1.0f}, {0.0f, 0.0f, 1.0f}, kWidth,
                          kHeight, 60.0f);
}

// A floor with two unit boxes near the left and right borders of edges_camera: the left
// one half inside the frame, the right one just outside it, so its occlusion on the floor
// inside the frame comes from geometry the frame never shows.
inline raycast::Scene edges_scene() {
  raycast::Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(0.0f, 0.0f, 1.0f), glm::vec3(0.8f)});
  raycast::Box a;
  a.centre_world = {-2.45f, 0.0f, 0.5f};
  a.half_extents_world = glm::vec3(0.5f);
  s.boxes.push_back(a);
  raycast::Box b = a;
  b.centre_world = {3.05f, 0.0f, 0.5f};
  s.boxes.push_back(b);
  return s;
}
inline Camera edges_camera(int width_px = kWidth, int height_px = kHeight,
                           float fov_x_deg = 60.0f) {
  return raycast::look_at({0.0f, -4.0f, 2.5f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, width_px,
                          height_px, fov_x_deg);
}

// The camera of the pan (frame t of 8): eye and target move 0.25 units per frame along +X,
// so the box at x = -1.6 slides out of the left border.
inline raycast::Scene pan_scene() {
  raycast::Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(0.0f, 0.0f, 1.0f), glm::vec3(0.8f)});
  s.planes.push_back({glm::vec3(0.0f, 3.0f, 0.0f), glm::vec3(0.0f, -1.0f, 0.0f), glm::vec3(0.8f)});
  raycast::Box b;
  b.centre_world = {-1.6f, 1.0f, 0.4f};
  b.half_extents_world = {0.4f, 0.4f, 0.4f};
  s.boxes.push_back(b);
  return s;
}
inline Camera pan_camera(int t) {
  const float dx = 0.25f * float(t);
  return raycast::look_at({dx, -3.0f, 1.8f}, {dx, 1.5f, 0.3f}, {0.0f, 0.0f, 1.0f}, kWidth,
                          kHeight, 60.0f);
}
inline constexpr int kPanFrames = 8;

// ---------------------------------------------------------------------------------------
// Degradations.

// Planar depth through half precision (IEEE binary16: 11-bit significand, relative
// rounding 2^-11 = 4.9e-4).
inline void degrade_half(GBuffer& g) {
  cv::Mat h;
  g.depth_view.convertTo(h, CV_16F);
  h.convertTo(g.depth_view, CV_32F);
  recompute_positions(g);
}

// The hardware depth buffer: window depth z_w = (ndc_z + 1) / 2 of the camera's
// projection (near 0.05, far 1000: from_fov_x's defaults) stored as 16-bit UNORM and
// converted back to planar depth. Relative step dz / z = z (f - n) / (f n) / 65535:
// 1.5e-3 at z = 5, above the default bias (1e-3).
inline void degrade_unorm16(GBuffer& g) {
  const glm::mat4& m = g.camera.view_to_clip;
  const float a = m[2][2], b = m[3][2];  // clip.z = a z + b, clip.w = -z
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      float& d = g.depth_view.at<float>(y, x);
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const double ndc = (double(a) * -d + b) / d;  // clip.z / clip.w with z = -d
      const double zw = std::round((0.5 * ndc + 0.5) * 65535.0) / 65535.0;
      const double ndc_q = 2.0 * zw - 1.0;
      d = float(b / (ndc_q + a));  // solve (a (-d) + b) / d = ndc_q for d
    }
  recompute_positions(g);
}

// Normals with Gaussian-like noise (sum of three uniforms, standard deviation sigma per
// component) added and renormalised, kept facing the camera; deterministic (noise.h).
inline void degrade_noisy_normals(GBuffer& g, float sigma = 0.15f) {
  for (int y = 0; y < g.normal_view.rows; ++y)
    for (int x = 0; x < g.normal_view.cols; ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      cv::Vec3f& n = g.normal_view.at<cv::Vec3f>(y, x);
      glm::vec3 v(n[0], n[1], n[2]);
      for (int c = 0; c < 3; ++c) {
        // Sum of 3 uniforms on [-1, 1]: variance 1, so sigma scales it directly.
        float e = 0.0f;
        for (int k = 0; k < 3; ++k) e += 2.0f * noise01(x, y, uint32_t(3 * c + k), 99u) - 1.0f;
        v[c] += sigma * e;
      }
      v = glm::normalize(v);
      const cv::Vec3f pv = g.position_view.at<cv::Vec3f>(y, x);
      if (glm::dot(v, glm::vec3(pv[0], pv[1], pv[2])) > 0.0f) v = -v;  // face the eye
      n = cv::Vec3f(v.x, v.y, v.z);
    }
}

inline void degrade_missing_normals(GBuffer& g) {
  g.normal_view.release();
  reconstruct_normals_from_depth(g.depth_view, g.mask, g.camera, g.normal_view, {}, 0);
}

// Non-finite and background values written into ~4% of the foreground pixels (single
// pixels and a 6x6 block), cycling NaN, +Inf, -Inf and 1e10 (Cycles' "no hit"); then masked
// as formats/gbuffer_reader.cpp does: mask 0, depth +inf, normal and position 0. Returns the
// injected values' pixels (CV_8UC1, 255 = injected).
inline cv::Mat inject_nonfinite(Frame& f) {
  GBuffer& g = f.input;
  cv::Mat injected = cv::Mat::zeros(g.depth_view.size(), CV_8UC1);
  const float values[] = {std::numeric_limits<float>::quiet_NaN(), kInf, -kInf, 1e10f};
  int k = 0;
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      const bool block = x >= 70 && x < 76 && y >= 50 && y < 56;
      if (!g.mask.at<uint8_t>(y, x)) continue;
      if (!block && noise01(x, y, 0, 1234u) >= 0.035f) continue;
      g.depth_view.at<float>(y, x) = values[k++ % 4];
      injected.at<uint8_t>(y, x) = 255;
    }
  // The reader's masking (gbuffer_reader.cpp): non-finite or background depth -> masked.
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      float& d = g.depth_view.at<float>(y, x);
      if (std::isfinite(d) && d > 0.0f && d < 1e10f) continue;
      d = kInf;
      g.mask.at<uint8_t>(y, x) = 0;
      g.normal_view.at<cv::Vec3f>(y, x) = cv::Vec3f(0, 0, 0);
      g.position_view.at<cv::Vec3f>(y, x) = cv::Vec3f(0, 0, 0);
      g.albedo.at<cv::Vec3f>(y, x) = cv::Vec3f(0, 0, 0);
      if (!g.depth_back_view.empty()) g.depth_back_view.at<float>(y, x) = kInf;
    }
  f.eval_mask.setTo(0, injected);
  return injected;
}

// Pixels of a plane seen at 80-89 degrees from its normal (view ray vs normal).
inline void keep_grazing(Frame& f) {
  for (int y = 0; y < f.eval_mask.rows; ++y)
    for (int x = 0; x < f.eval_mask.cols; ++x) {
      if (!f.eval_mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f p = f.input.position_view.at<cv::Vec3f>(y, x);
      const cv::Vec3f n = f.input.normal_view.at<cv::Vec3f>(y, x);
      const float c = -n.dot(p) / float(cv::norm(p));
      const float angle_deg = std::acos(std::clamp(c, -1.0f, 1.0f)) * 57.29578f;
      if (angle_deg < 80.0f || angle_deg > 89.0f) f.eval_mask.at<uint8_t>(y, x) = 0;
    }
}

// ---------------------------------------------------------------------------------------
// The suite.

inline const std::vector<std::string>& case_names() {
  static const std::vector<std::string> names = {
      "thin", "floating", "edges", "grazing", "cornell", "half", "unorm16",
      "noisy_normals", "no_normals", "nonfinite", "pan"};
  return names;
}

// Builds one case by name (see case_names()); a few seconds each on 2 cores (the
// reference's 256 rays per pixel).
inline Case build_case(const std::string& name) {
  auto single = [&](std::string title, raycast::Scene scene, Camera cam) {
    Case c{name, std::move(title), {}, scene};
    c.frames.push_back(clean_frame(scene, cam));
    return c;
  };
  const glm::vec3 up(0.0f, 0.0f, 1.0f);
  if (name == "thin")
    return single("1 thin occluders (poles, plate)", thin_scene(), raycast::poles_camera(kWidth, kHeight));
  if (name == "floating")
    return single("2 depth discontinuities", floating_near_scene(), floating_near_camera());
  if (name == "edges") return single("3 screen edges", edges_scene(), edges_camera());
  if (name == "grazing") {
    // Elevation 4 degrees: the rows below the horizon span ~70-90 degrees from the normal.
    Case c = single("4 grazing floor (80-89 deg)", raycast::open_plane(up),
                    raycast::open_plane_camera(up, 4.0f, kWidth, kHeight));
    keep_grazing(c.frames[0]);
    return c;
  }
  if (name == "pan") {
    Case c{name, "8 camera pan (8 frames)", {}, pan_scene()};
    for (int t = 0; t < kPanFrames; ++t) c.frames.push_back(clean_frame(c.scene, pan_camera(t)));
    return c;
  }
  // Cases 5-7 degrade the cornell frame; "cornell" is the undegraded one, their baseline.
  Case c = single("", raycast::cornell_scene(), raycast::cornell_camera(kWidth, kHeight));
  Frame& f = c.frames[0];
  if (name == "cornell") c.title = "0 cornell, clean (baseline of 5-7)";
  else if (name == "half") c.title = "5a half-float depth", degrade_half(f.input);
  else if (name == "unorm16") c.title = "5b 16-bit window depth", degrade_unorm16(f.input);
  else if (name == "noisy_normals") c.title = "6a noisy normals (sigma 0.15)", degrade_noisy_normals(f.input);
  else if (name == "no_normals") c.title = "6b normals from depth", degrade_missing_normals(f.input);
  else if (name == "nonfinite") c.title = "7 NaN/Inf/1e10 pixels", inject_nonfinite(f);
  else throw std::invalid_argument("unknown failure case " + name);
  return c;
}

inline std::vector<Case> build_cases() {
  std::vector<Case> cases;
  for (const std::string& n : case_names()) cases.push_back(build_case(n));
  return cases;
}

// The estimators of the table: every method at every preset; raymarch at low only (64 rays
// x 32 steps; its higher presets only lower its noise and cost seconds per frame).
struct Estimator {
  AoMethod method;
  Preset preset;
  std::string name() const { return std::string(to_string(method)) + " " + std::string(to_string(preset)); }
};

inline std::vector<Estimator> estimators() {
  std::vector<Estimator> e;
  for (AoMethod m : {AoMethod::hemisphere, AoMethod::hbao, AoMethod::gtao})
    for (Preset p : {Preset::low, Preset::medium, Preset::high, Preset::ultra}) e.push_back({m, p});
  e.push_back({AoMethod::raymarch, Preset::low});
  return e;
}

inline AoSettings settings_of(const Estimator& e) {
  AoSettings s = ao_preset(e.method, e.preset);
  s.radius_world = kRadius;
  return s;
}

// Runs one estimator on a frame; use_back: pass the frame's back-face depth.
inline cv::Mat run(const Frame& f, const AoSettings& s, bool use_back = false) {
  const GBuffer& g = f.input;
  const AoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera,
                    g.albedo.empty() ? nullptr : &g.albedo,
                    use_back && !g.depth_back_view.empty() ? &g.depth_back_view : nullptr};
  AoOutput out;
  compute_ao_at_resolution(in, s, out, {}, 0);
  return out.ao;
}

inline cv::Mat confidence_of(const Frame& f, const AoSettings& s) {
  ConfidenceSettings cs;
  cs.radius_world = s.radius_world;
  cs.max_radius_px = s.max_radius_px;
  cv::Mat c;
  compute_confidence_at_resolution(f.input.depth_view, f.input.normal_view, f.input.mask, f.input.camera, cs, c,
                                   {}, 0);
  return c;
}

struct Errors {
  double mae = 0, max_abs = 0;
  int64_t pixels = 0;
};

// Absolute error statistics of estimate vs reference over mask (non-finite estimates count
// as error 1: they must not exist).
inline Errors errors(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask) {
  Errors e;
  double sum = 0;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const float v = estimate.at<float>(y, x);
      const double d = std::isfinite(v) ? std::abs(double(v) - reference.at<float>(y, x)) : 1.0;
      sum += d;
      e.max_abs = std::max(e.max_abs, d);
      ++e.pixels;
    }
  e.mae = e.pixels ? sum / double(e.pixels) : 0.0;
  return e;
}

// Temporal flicker of a sequence: the mean |out_t(x) - out_{t-1}(x')| over pixels x of
// frame t whose surface point reprojects with frame t-1's camera to pixel x' showing the
// same point (within 1% of its depth: not disoccluded) and whose reference does not change
// (|ref_t(x) - ref_{t-1}(x')| < 0.05: about 1.6 standard deviations of the reference's
// own MC noise, so pixels whose true AO changes, e.g. as an occluder leaves the view, are
// excluded, as their change is not flicker).
inline double flicker(const std::vector<Frame>& frames, const std::vector<cv::Mat>& outputs) {
  double sum = 0;
  int64_t n = 0;
  for (size_t t = 1; t < frames.size(); ++t) {
    const Frame& cur = frames[t];
    const Frame& prev = frames[t - 1];
    for (int y = 0; y < cur.eval_mask.rows; ++y)
      for (int x = 0; x < cur.eval_mask.cols; ++x) {
        if (!cur.eval_mask.at<uint8_t>(y, x)) continue;
        const cv::Vec3f pw = cur.position_world.at<cv::Vec3f>(y, x);
        const glm::vec3 p(pw[0], pw[1], pw[2]);
        const glm::vec3 pv = prev.input.camera.view_from_world_point(p);
        const glm::vec2 px = prev.input.camera.pixel_from_view(pv);
        if (!(px.x >= 0.0f && px.y >= 0.0f && px.x < float(kWidth) && px.y < float(kHeight))) continue;
        const int xp = int(px.x), yp = int(px.y);
        if (!prev.eval_mask.at<uint8_t>(yp, xp)) continue;
        const cv::Vec3f qw = prev.position_world.at<cv::Vec3f>(yp, xp);
        const float dist = glm::length(glm::vec3(qw[0], qw[1], qw[2]) - p);
        if (dist > 0.01f * -pv.z + 0.02f) continue;  // another surface, or a pixel apart on a slope
        if (std::abs(cur.reference.at<float>(y, x) - prev.reference.at<float>(yp, xp)) >= 0.05f)
          continue;
        sum += std::abs(double(outputs[t].at<float>(y, x)) - outputs[t - 1].at<float>(yp, xp));
        ++n;
      }
  }
  return n ? sum / double(n) : 0.0;
}

// Errors over all frames of a case (pixel-weighted MAE, max over frames).
inline Errors case_errors(const Case& c, const std::vector<cv::Mat>& outputs) {
  Errors all;
  double sum = 0;
  for (size_t t = 0; t < c.frames.size(); ++t) {
    const Errors e = errors(outputs[t], c.frames[t].reference, c.frames[t].eval_mask);
    sum += e.mae * double(e.pixels);
    all.pixels += e.pixels;
    all.max_abs = std::max(all.max_abs, e.max_abs);
  }
  all.mae = all.pixels ? sum / double(all.pixels) : 0.0;
  return all;
}

// Mean error of the pixels with confidence below `low` and above `high`.
struct ConfidenceSplit {
  double sum_low = 0, sum_high = 0;
  int64_t n_low = 0, n_high = 0, n = 0;
  void add(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask,
           const cv::Mat& confidence, double low = 0.5, double high = 0.9) {
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) {
        if (!mask.at<uint8_t>(y, x)) continue;
        const double e = std::abs(double(estimate.at<float>(y, x)) - reference.at<float>(y, x));
        const float c = confidence.at<float>(y, x);
        ++n;
        if (c < low) sum_low += e, ++n_low;
        if (c > high) sum_high += e, ++n_high;
      }
  }
  double mean_low() const { return n_low ? sum_low / double(n_low) : 0.0; }
  double mean_high() const { return n_high ? sum_high / double(n_high) : 0.0; }
};

}  // namespace ssdo::failure
