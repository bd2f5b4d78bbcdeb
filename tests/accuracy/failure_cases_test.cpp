// Where screen-space AO fails: the failure-case suite (failure_cases.h) against the
// ray-traced references, with regression thresholds per case and estimator, the measured
// gain of each mitigation (thickness, back-face depth, guard band, relative bias), the
// edge policy (no occlusion from clamped taps) and the confidence output's correlation
// with the real error. The printed tables are docs/accuracy.md's "Where screen space fails".
#include <chrono>
#include <cstdio>
#include <functional>
#include <map>
#include <stdexcept>

#include <gtest/gtest.h>

#include "kernels/half_resolution.h"
#include "kernels/ao_raymarch.h"
#include "kernels/thickness.h"
#include "tests/accuracy/failure_cases.h"

namespace ssdo::failure {
namespace {

// Cases are built on first use and kept: CTest runs the suite in one process
// (PER_SUITE, tests/CMakeLists.txt), whose tests share them, and a test run alone builds
// only the cases it reads.
const Case& find_case(const std::string& name) {
  static std::map<std::string, Case> cache;
  auto it = cache.find(name);
  if (it == cache.end()) it = cache.emplace(name, build_case(name)).first;
  return it->second;
}

std::vector<std::reference_wrapper<const Case>> suite() {
  std::vector<std::reference_wrapper<const Case>> all;
  for (const std::string& n : case_names()) all.push_back(std::cref(find_case(n)));
  return all;
}

struct Result {
  Errors err;
  double flicker = 0;
};

// Outputs are memoised per (case, settings): the tables share most of their runs.
const std::vector<cv::Mat>& outputs_of(const Case& c, const AoSettings& s, bool use_back) {
  static std::map<std::string, std::vector<cv::Mat>> cache;
  char key[256];
  std::snprintf(key, sizeof key, "%s|%d|%d|%d|%d|%d|%g|%g|%g|%d|%d", c.name.c_str(), int(s.method),
                s.samples, s.directions, s.steps, s.resolution_divisor, double(s.thickness_world),
                double(s.depth_bias_relative), double(s.radius_world), int(use_back),
                int(s.seed));
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  std::vector<cv::Mat> outputs;
  for (const Frame& f : c.frames) outputs.push_back(run(f, s, use_back));
  return cache.emplace(key, std::move(outputs)).first->second;
}

Result evaluate(const Case& c, const AoSettings& s, bool use_back = false,
                std::vector<cv::Mat>* outputs_out = nullptr) {
  const std::vector<cv::Mat>& outputs = outputs_of(c, s, use_back);
  Result r;
  r.err = case_errors(c, outputs);
  if (c.frames.size() > 1) r.flicker = flicker(c.frames, outputs);
  if (outputs_out) *outputs_out = outputs;
  return r;
}

// Measured MAE of every estimator on every case (the printed table), plus slack: 20% and
// 0.01 (noise-pattern changes move a 160x90 frame's MAE by a few thousandths).
double threshold(double measured) { return 1.2 * measured + 0.01; }

// The measured MAE per case (columns in case_names() order, then the pan's flicker) and
// estimator (rows): the values of the table in docs/accuracy.md when it was written.
const std::map<std::string, std::vector<double>>& measured_mae() {
  static const std::map<std::string, std::vector<double>> m = {
    {"hemisphere low", {0.084, 0.047, 0.029, 0.000, 0.191, 0.191, 0.190, 0.189, 0.191, 0.191, 0.065, 0.0081}},
    {"hemisphere medium", {0.082, 0.047, 0.028, 0.000, 0.192, 0.192, 0.191, 0.190, 0.192, 0.192, 0.067, 0.0044}},
    {"hemisphere high", {0.080, 0.047, 0.027, 0.000, 0.189, 0.189, 0.189, 0.189, 0.189, 0.191, 0.062, 0.0069}},
    {"hemisphere ultra", {0.078, 0.047, 0.027, 0.001, 0.189, 0.189, 0.189, 0.184, 0.189, 0.190, 0.060, 0.0040}},
    {"hbao low", {0.054, 0.044, 0.015, 0.000, 0.127, 0.127, 0.127, 0.126, 0.127, 0.126, 0.029, 0.0178}},
    {"hbao medium", {0.057, 0.042, 0.012, 0.000, 0.109, 0.110, 0.109, 0.110, 0.109, 0.109, 0.021, 0.0105}},
    {"hbao high", {0.069, 0.047, 0.012, 0.000, 0.097, 0.097, 0.097, 0.105, 0.097, 0.098, 0.016, 0.0107}},
    {"hbao ultra", {0.089, 0.051, 0.010, 0.000, 0.082, 0.082, 0.082, 0.093, 0.082, 0.082, 0.012, 0.0056}},
    {"gtao low", {0.046, 0.038, 0.022, 0.000, 0.122, 0.123, 0.123, 0.123, 0.122, 0.121, 0.033, 0.0364}},
    {"gtao medium", {0.031, 0.029, 0.013, 0.000, 0.098, 0.098, 0.098, 0.099, 0.098, 0.097, 0.018, 0.0137}},
    {"gtao high", {0.031, 0.036, 0.011, 0.000, 0.078, 0.078, 0.078, 0.088, 0.078, 0.081, 0.013, 0.0114}},
    {"gtao ultra", {0.025, 0.030, 0.008, 0.000, 0.070, 0.070, 0.070, 0.081, 0.070, 0.074, 0.009, 0.0058}},
    {"raymarch low", {0.100, 0.032, 0.010, 0.000, 0.072, 0.072, 0.072, 0.094, 0.073, 0.073, 0.012, 0.0090}},
  };
  return m;
}

TEST(FailureCases, TableAgainstReference) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto cases = suite();
  std::printf("suite built in %.1f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  std::printf("%-18s", "MAE / max");
  for (const Case& c : cases) std::printf(" | %-13s", c.name.c_str());
  std::printf(" | pan flicker\n");
  for (const Estimator& e : estimators()) {
    const AoSettings s = settings_of(e);
    std::printf("%-18s", e.name().c_str());
    std::vector<double> maes;
    double fl = 0;
    for (const Case& c : cases) {
      const Result r = evaluate(c, s);
      maes.push_back(r.err.mae);
      if (c.frames.size() > 1) fl = r.flicker;
      std::printf(" | %.3f / %.2f  ", r.err.mae, r.err.max_abs);
    }
    std::printf(" | %.4f\n", fl);
    std::printf("  {\"%s\", {", e.name().c_str());
    for (double v : maes) std::printf("%.3f, ", v);
    std::printf("%.4f}},\n", fl);
    const auto it = measured_mae().find(e.name());
    if (it == measured_mae().end()) continue;
    for (size_t k = 0; k < cases.size(); ++k)
      EXPECT_LE(maes[k], threshold(it->second[k])) << e.name() << " on " << cases[k].get().name;
    // Flicker is a few thousandths: 50% and 0.003 of slack.
    EXPECT_LE(fl, 1.5 * it->second.back() + 0.003) << e.name() << " flicker";
  }
  const double flicker_ref = [&] {
    const Case& pan = find_case("pan");
    std::vector<cv::Mat> refs;
    for (const Frame& f : pan.frames) refs.push_back(f.reference);
    return flicker(pan.frames, refs);
  }();
  std::printf("reference's own flicker (MC noise floor): %.4f\n", flicker_ref);
}

// The estimators of the mitigation tables: each method at its high preset, raymarch low.
std::vector<Estimator> mitigation_estimators() {
  return {{AoMethod::hemisphere, Preset::high}, {AoMethod::hbao, Preset::high},
          {AoMethod::gtao, Preset::high}, {AoMethod::raymarch, Preset::low}};
}


// Thickness model: every surface taken as 0.5 x radius deep (the default) against a height
// field (thickness inf), on every case (the gain on 1 and 2 must not cost elsewhere).
TEST(FailureCases, MitigationThickness) {
  std::printf("thickness inf -> 0.5 x radius: MAE per case\n");
  for (const Estimator& e : mitigation_estimators()) {
    if (e.method == AoMethod::hbao) continue;  // a height field by construction
    AoSettings before = settings_of(e), after = settings_of(e);
    before.thickness_world = kInf;
    std::printf("%-16s", e.name().c_str());
    for (const char* name : {"thin", "floating", "edges", "cornell", "pan"}) {
      const Case& c = find_case(name);
      const double b = evaluate(c, before).err.mae, a = evaluate(c, after).err.mae;
      std::printf(" %s %.3f->%.3f", c.name.c_str(), b, a);
      // GTAO's visibility mask and raymarch's slab test gain on 1 and 2; hemisphere's
      // per-tap cut does not (a tap beyond the thickness is dropped, not replaced by
      // what is behind it): no gain, and no loss above 0.01 either.
      if ((c.name == "thin" || c.name == "floating") && e.method != AoMethod::hemisphere) {
        EXPECT_LT(a, b) << e.name() << " " << c.name;
      } else {
        EXPECT_LE(a, b + 0.01) << e.name() << " " << c.name;
      }
    }
    std::printf("\n");
  }
}

// Second depth layer: the back-face pass as each tap's own thickness, against the 0.5 x
// radius guess. On the thin case the MAE with it must fall below thin_factor x without;
// elsewhere it may not rise by more than 0.005.
void check_back_face_depth(const char* label, const AoSettings& s, double thin_factor) {
  std::printf("back-face depth (%s): MAE without -> with\n", label);
  for (const Case& c : suite()) {
    const Result b = evaluate(c, s, false), a = evaluate(c, s, true);
    std::printf("  %-14s %.3f -> %.3f   max %.2f -> %.2f   flicker %.4f -> %.4f\n",
                c.name.c_str(), b.err.mae, a.err.mae, b.err.max_abs, a.err.max_abs, b.flicker,
                a.flicker);
    if (c.name == "thin") {
      EXPECT_LT(a.err.mae, thin_factor * b.err.mae);
    } else {
      EXPECT_LE(a.err.mae, b.err.mae + 0.005) << c.name;
    }
  }
}

TEST(FailureCases, MitigationBackFaceDepth) {
  check_back_face_depth("raymarch low", settings_of({AoMethod::raymarch, Preset::low}), 0.8);
}

// The same for GTAO's visibility mask, at high (full resolution; the half grid of low and
// medium samples the back layer at its texels).
TEST(FailureCases, MitigationBackFaceDepthGtao) {
  check_back_face_depth("gtao high", settings_of({AoMethod::gtao, Preset::high}), 1.0);
}

// Thickness from silhouettes (kernels/thickness.h, --thickness-model silhouettes) against
// the 0.5 x radius guess, GTAO at every preset (the back layer estimated from the frame's
// depth at full resolution; the half grid samples it at its texels): the thin case's poles
// and plates become thin and the synthetic cornell's walls solid, both well below the
// guess; an object floating free is taken thinner at its rim than it is, and may err up to
// 0.01 more (measured 2026-12-06: +0.003 to +0.009, high's the most); the edges case
// within 0.005.
TEST(FailureCases, MitigationSilhouetteThickness) {
  std::printf("thickness 0.5 x radius -> from silhouettes: MAE per case\n");
  const char* const names[] = {"thin", "floating", "edges", "cornell"};
  // Each case's frame with the estimate in place of its back-face pass (a new image: the
  // cached case keeps its own).
  std::vector<Frame> estimated;
  for (const char* name : names) {
    Frame f = find_case(name).frames[0];
    cv::Mat back;
    estimate_back_depth(f.input.depth_view, f.input.mask, f.input.camera, {}, back, 0);
    f.input.depth_back_view = back;
    estimated.push_back(f);
  }
  for (Preset p : {Preset::low, Preset::medium, Preset::high}) {
    const Estimator e{AoMethod::gtao, p};
    AoSettings s = settings_of(e);
    s.thickness_model = ThicknessModel::constant;  // before; after: the layer given
    std::printf("%-16s", e.name().c_str());
    for (size_t i = 0; i < estimated.size(); ++i) {
      const Frame& f = estimated[i];
      const char* name = names[i];
      const double b = errors(run(f, s), f.reference, f.eval_mask).mae;
      const double a = errors(run(f, s, true), f.reference, f.eval_mask).mae;
      std::printf(" %s %.4f->%.4f", name, b, a);
      const std::string n = name;
      if (n == "thin") EXPECT_LT(a, 0.8 * b) << e.name();
      else if (n == "cornell") EXPECT_LT(a, 0.97 * b) << e.name();
      else if (n == "floating") EXPECT_LE(a, b + 0.01) << e.name();
      else EXPECT_LE(a, b + 0.005) << e.name() << " " << n;
    }
    std::printf("\n");
  }
}

// Guard band: the renderer draws kGuard pixels more on every side (the same projection per
// pixel: a wider field of view), the methods run on the larger frame and the centre is
// cropped. The occluders just outside the frame are then seen.
constexpr int kGuard = 16;

TEST(FailureCases, MitigationGuardBand) {
  const Case& edges = find_case("edges");
  const Frame& plain = edges.frames[0];
  const float half_fov = glm::radians(30.0f);
  const float fov_guard =
      2.0f * std::atan(std::tan(half_fov) * float(kWidth + 2 * kGuard) / float(kWidth));
  Frame guard;
  guard.input = raycast::render_gbuffer(
      edges.scene, edges_camera(kWidth + 2 * kGuard, kHeight + 2 * kGuard, glm::degrees(fov_guard)), 0);
  const cv::Rect centre(kGuard, kGuard, kWidth, kHeight);
  // The centre of the guard-band frame is the plain frame's pixel grid.
  cv::Mat diff;
  cv::absdiff(guard.input.depth_view(centre), plain.input.depth_view, diff);
  diff.setTo(0, plain.input.mask == 0);
  double max_diff;
  cv::minMaxLoc(diff, nullptr, &max_diff);
  ASSERT_LT(max_diff, 1e-3);
  std::printf("guard band %d px: edges MAE (max) without -> with\n", kGuard);
  for (const Estimator& e : mitigation_estimators()) {
    const AoSettings s = settings_of(e);
    const Errors b = errors(run(plain, s), plain.reference, plain.eval_mask);
    const cv::Mat cropped = run(guard, s)(centre).clone();
    const Errors a = errors(cropped, plain.reference, plain.eval_mask);
    std::printf("  %-16s %.3f (%.2f) -> %.3f (%.2f)\n", e.name().c_str(), b.mae, b.max_abs, a.mae,
                a.max_abs);
    EXPECT_LT(a.mae, b.mae) << e.name();
    EXPECT_LE(a.max_abs, b.max_abs + 0.05) << e.name();  // one pixel's noise
  }
}

// No occlusion invented from clamped taps: an open plane (AO = 1 everywhere) tilted so
// that depth grows towards the top border. A tap beyond the top border clamped to the
// border row would read a depth nearer than the plane there and occlude; off-screen taps
// must count as unknown (open). Every method, every preset: the top rows stay open.
TEST(FailureCases, NoOcclusionFromClampedTaps) {
  const glm::vec3 up(0.0f, 0.0f, 1.0f);
  const raycast::Scene plane = raycast::open_plane(up);
  GBuffer g = raycast::render_gbuffer(plane, raycast::open_plane_camera(up, 35.0f, kWidth, kHeight), 0);
  Frame f;
  f.input = g;
  for (const Estimator& e : estimators()) {
    const cv::Mat ao = run(f, settings_of(e));
    double lo_top = 1.0, lo_all = 1.0;
    for (int y = 0; y < ao.rows; ++y)
      for (int x = 0; x < ao.cols; ++x) {
        if (!g.mask.at<uint8_t>(y, x)) continue;
        lo_all = std::min(lo_all, double(ao.at<float>(y, x)));
        if (y < 8 || x < 8 || x >= kWidth - 8) lo_top = std::min(lo_top, double(ao.at<float>(y, x)));
      }
    EXPECT_GT(lo_top, 0.97) << e.name() << ": border rows occluded";
    EXPECT_GT(lo_all, 0.97) << e.name();
  }
}

// Relative depth bias on low-precision depth: bias 0 against the default 1e-3 x depth.
TEST(FailureCases, MitigationRelativeBias) {
  std::printf("depth bias 0 -> 1e-3 x depth: MAE (cornell clean / half / unorm16)\n");
  for (const Estimator& e : mitigation_estimators()) {
    AoSettings before = settings_of(e), after = settings_of(e);
    before.depth_bias_relative = 0.0f;
    std::printf("  %-16s", e.name().c_str());
    for (const char* name : {"cornell", "half", "unorm16"}) {
      const Case& c = find_case(name);
      const double b = evaluate(c, before).err.mae, a = evaluate(c, after).err.mae;
      std::printf(" %s %.3f->%.3f", name, b, a);
      EXPECT_LE(a, b + 0.002) << e.name() << " " << name;
    }
    // The hardest low-precision input: 16-bit window depth and no normals (reconstructed
    // from the quantised depth, as for a depth-only frame).
    Case raw = find_case("unorm16");
    raw.name = "unorm16_no_normals";
    degrade_missing_normals(raw.frames[0].input);
    const double b = evaluate(raw, before).err.mae, a = evaluate(raw, after).err.mae;
    std::printf(" unorm16+normals from depth %.3f->%.3f\n", b, a);
    EXPECT_LE(a, b + 0.002) << e.name() << " unorm16 + normals from depth";
  }
}

// Non-finite and background pixels, masked as the reader does: no output is non-finite or
// outside [0, 1], and the error on the remaining pixels stays that of the clean frame.
TEST(FailureCases, NonFiniteDoesNotPropagate) {
  const Case& dirty = find_case("nonfinite");
  const Case& clean = find_case("cornell");
  for (const Estimator& e : estimators()) {
    const AoSettings s = settings_of(e);
    const cv::Mat ao = run(dirty.frames[0], s);
    int bad = 0;
    for (int y = 0; y < ao.rows; ++y)
      for (int x = 0; x < ao.cols; ++x) {
        const float v = ao.at<float>(y, x);
        if (!(v >= 0.0f && v <= 1.0f)) ++bad;
      }
    EXPECT_EQ(bad, 0) << e.name();
    const double a = errors(ao, dirty.frames[0].reference, dirty.frames[0].eval_mask).mae;
    const double b = errors(run(clean.frames[0], s), clean.frames[0].reference,
                            dirty.frames[0].eval_mask).mae;
    EXPECT_LE(a, b + 0.01) << e.name();
    const cv::Mat conf = confidence_of(dirty.frames[0], s);
    EXPECT_EQ(cv::countNonZero(conf != conf), 0);
  }
}

// Confidence against the real error on the whole suite: pixels with confidence < 0.5 have
// a clearly larger mean error than those with confidence > 0.9, for every method.
TEST(FailureCases, ConfidenceCorrelatesWithError) {
  std::printf("confidence vs |error| over the suite: mean error (pixels) conf<0.5 | conf>0.9\n");
  for (const Estimator& e : mitigation_estimators()) {
    const AoSettings s = settings_of(e);
    ConfidenceSplit split;
    for (const Case& c : suite())
      for (const Frame& f : c.frames)
        split.add(run(f, s), f.reference, f.eval_mask, confidence_of(f, s));
    std::printf("  %-16s %.3f (%lld) | %.3f (%lld) of %lld\n", e.name().c_str(), split.mean_low(),
                (long long)split.n_low, split.mean_high(), (long long)split.n_high,
                (long long)split.n);
    EXPECT_GT(split.n_low, 100);
    EXPECT_GT(split.mean_low(), 1.5 * split.mean_high()) << e.name();
  }
}

TEST(Confidence, OpenPlaneIsObservedAndThreadCountIndependent) {
  const glm::vec3 up(0.0f, 0.0f, 1.0f);
  Frame f;
  f.input = raycast::render_gbuffer(raycast::open_plane(up),
                                    raycast::open_plane_camera(up, 60.0f, kWidth, kHeight), 0);
  AoSettings s;
  s.radius_world = 0.3f;
  const cv::Mat c1 = confidence_of(f, s);
  // Away from the borders (radius 0.3 at depth ~4: ~17 px) every tap is on the plane.
  const cv::Rect inner(24, 24, kWidth - 48, kHeight - 48);
  double lo;
  cv::minMaxLoc(c1(inner), &lo, nullptr, nullptr, nullptr, f.input.mask(inner));
  EXPECT_GT(lo, 0.999);
  ConfidenceSettings cs;
  cs.radius_world = s.radius_world;
  cv::Mat serial, parallel;
  compute_confidence_at_resolution(f.input.depth_view, f.input.normal_view, f.input.mask, f.input.camera, cs,
                                   serial, {}, 1);
  compute_confidence_at_resolution(f.input.depth_view, f.input.normal_view, f.input.mask, f.input.camera, cs,
                                   parallel, {}, 4);
  EXPECT_EQ(cv::norm(serial, parallel, cv::NORM_INF), 0.0);
  // At the border about half of the disk is off screen.
  double border = 0;
  int n = 0;
  for (int y = 30; y < 60; ++y)
    if (f.input.mask.at<uint8_t>(y, 0)) border += serial.at<float>(y, 0), ++n;
  ASSERT_GT(n, 0);
  EXPECT_NEAR(border / n, 0.5, 0.1);
}

}  // namespace
}  // namespace ssdo::failure
