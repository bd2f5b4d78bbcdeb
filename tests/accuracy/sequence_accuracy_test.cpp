// Neighbouring frames as extra views (kernels/multiview.h) on a synthetic shot of the
// reference ray caster (tests/support/raycast.h), where the exact AO is known: the camera
// trucks sideways over a floor and a wall scattered with boxes, slabs and thin poles, so
// occluders enter and leave the picture across its edges, and hidden ones (the back of a
// pole, a box behind a box) come into view from the neighbours. The denoised AO of each
// frame computed alone, with the views the service picks for the default `--views`, and
// with every frame t-K..t+K of the shot as a view, against the ray-traced AO: the shot must
// improve and no frame may get worse by more than 2% of its single-frame error. Over the
// border band, the pixels whose AO neighbourhood reaches past the left or right screen edge
// (there the off-screen taps the views fill in the guard band help most), the shot must
// improve by kMinBorderGain; the frame rendered with overscan (every off-screen tap known)
// is printed there as the bound.
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>

#include <gtest/gtest.h>

#include "service/frame_options.h"
#include "shot_views.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

constexpr int kFrames = raycast::kTruckShotFrames;
constexpr int kWidth = 192, kHeight = 108;
constexpr float kRadiusWorld = 1.0f;     // Cycles' default AO distance
// Reference: cosine-weighted rays per pixel within the radius (MC noise of a pixel: standard
// deviation <= 0.5 / sqrt(128) = 0.044, far less over a frame's mean error).
constexpr int kReferenceRays = 128;
constexpr uint32_t kReferenceSeed = 11;

// The shot's scene and cameras: raycast::truck_shot_scene (tests/support/raycast.h).
Camera shot_camera(int t, int guard_px = 0) { return raycast::truck_shot_camera(t, kWidth, kHeight, guard_px); }

// Foreground pixels whose AO neighbourhood (the radius projected at the pixel's depth)
// reaches past the left or right edge of the screen: the only pixels off-screen occluders
// shade. The shot trucks sideways, so they enter and leave across those edges; beyond the
// top and bottom ones lie only the wall and the floor going on.
cv::Mat border_band(const GBuffer& g, float radius_world) {
  cv::Mat band = cv::Mat::zeros(g.mask.size(), CV_8UC1);
  for (int y = 0; y < band.rows; ++y)
    for (int x = 0; x < band.cols; ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const float radius_px = radius_world * g.camera.pixels_per_unit(g.depth_view.at<float>(y, x)).x;
      if (std::min(float(x) + 0.5f, float(band.cols - x) - 0.5f) < radius_px) band.at<uint8_t>(y, x) = 255;
    }
  return band;
}

const raycast::Scene& scene() {
  static const raycast::Scene s = raycast::truck_shot_scene();
  return s;
}

struct ShotFrame {
  GBuffer g;
  cv::Mat reference;  // ray-traced AO, CV_32FC1
  cv::Mat border;     // border_band
};

const ShotFrame& shot_frame(int t) {
  static std::map<int, ShotFrame> cache;
  if (auto it = cache.find(t); it != cache.end()) return it->second;
  ShotFrame& f = cache[t];
  f.g = raycast::render_gbuffer(scene(), shot_camera(t));
  f.reference = raycast::reference_ao(scene(), f.g, kRadiusWorld, kReferenceRays, kReferenceSeed);
  f.border = border_band(f.g, kRadiusWorld);
  return f;
}

// The border band's share of the shot's foreground pixels.
double border_fraction() {
  double band = 0, foreground = 0;
  for (int t = 0; t < kFrames; ++t) {
    band += cv::countNonZero(shot_frame(t).border);
    foreground += cv::countNonZero(shot_frame(t).g.mask);
  }
  return band / foreground;
}

// The projected radius at the nearest depth of the shot: overscan by this much holds
// every off-screen tap of every pixel.
int overscan_px() {
  double nearest = std::numeric_limits<double>::infinity();
  for (int t = 0; t < kFrames; ++t) {
    double lo;
    cv::minMaxLoc(shot_frame(t).g.depth_view, &lo, nullptr, nullptr, nullptr, shot_frame(t).g.mask);
    nearest = std::min(nearest, lo);
  }
  return int(std::ceil(kRadiusWorld * shot_frame(0).g.camera.pixels_per_unit(float(nearest)).x));
}

// Frame t alone (the frame's own depth only), rendered with overscan and cropped: its AO
// if every off-screen tap found its geometry (what a guard band can reach), over the
// border band.
ErrorStats overscan_border_error(int t, AoMethod method, Preset preset) {
  const int guard = overscan_px();
  const GBuffer wide = raycast::render_gbuffer(scene(), shot_camera(t, guard));
  const ComputedFrame out =
      compute_frame(wide, shot::ao_request(method, preset, kRadiusWorld, ThicknessModel::constant));
  const cv::Mat ao = (*out.find("ao_denoised"))(cv::Rect(guard, guard, kWidth, kHeight));
  return compare_images(ao, shot_frame(t).reference, shot_frame(t).border);
}

// Which neighbours a frame gets: none, every frame within K (t-K..t+K), or those the
// service picks for `--views K` by parallax (service/view_selection.h).
enum class Views { none, window, chosen };

GBuffer frame_with_views(int t, Views views) {
  const shot::FrameOf frame = [](int u) -> const GBuffer& { return shot_frame(u).g; };
  const shot::NameOf name = [](int u) { return "shot_f" + std::to_string(u); };
  if (views == Views::chosen) return shot::with_chosen_views(t, kDefaultViewsPerSide, kFrames, frame, name);
  return shot::with_views(t, views == Views::window ? kDefaultViewsPerSide : 0, kFrames, frame, name);
}

// With the constant thickness unless told: what the views add to a frame's one guess (the
// GTAO presets' thickness from silhouettes, which leaves the views less to add, is measured
// in SilhouettesAndViewsTogetherErrLeast).
shot::Measured measure(const GBuffer& g, int t, AoMethod method, Preset preset,
                       ThicknessModel model = ThicknessModel::constant) {
  const ShotFrame& f = shot_frame(t);
  return shot::measure_denoised_ao(g, method, preset, kRadiusWorld, f.reference, f.g.mask, f.border, model);
}

// The shot's mean error with the default views must be at least this much below the frames
// computed alone (measured: 14-20% lower with the service's choice, 10-12% with t-2..t+2).
constexpr double kMinMeanGain = 0.05;
// And over the border band with the service's choice (measured: 10-13% lower with the
// guard band, 3-10% without it).
constexpr double kMinBorderGain = 0.08;

struct ShotMeans {
  double alone = 0, window = 0, chosen = 0;
};

// One row of the printed table (markdown): frame t's errors and times; asserts that no
// choice of views makes it worse by more than 2%. The raymarch oracle is the test's cost:
// it runs alone and with the service's views only (no t-K..t+K window, no overscan frame
// of 3.2x the pixels).
void measure_frame(int t, AoMethod method, Preset preset, ShotMeans& whole, ShotMeans& border, double& overscan) {
  const bool all = method != AoMethod::raymarch;
  const GBuffer chosen_g = frame_with_views(t, Views::chosen);
  const shot::Measured a = measure(frame_with_views(t, Views::none), t, method, preset);
  const shot::Measured c = measure(chosen_g, t, method, preset);
  const shot::Measured w = all ? measure(frame_with_views(t, Views::window), t, method, preset) : a;
  std::string names;
  for (const DepthView& v : chosen_g.views) {
    if (!names.empty()) names += ' ';
    names += v.name;
  }
  auto gain = [&](const shot::Measured& m) { return 100.0 * (m.whole.mae / a.whole.mae - 1.0); };
  std::printf("| f%d | %s | %.4f | ", t, names.c_str(), a.whole.mae);
  if (all) std::printf("%.4f (%+.0f%%)", w.whole.mae, gain(w));
  std::printf(" | %.4f (%+.0f%%) | %.4f | ", c.whole.mae, gain(c), a.border.mae);
  if (all) std::printf("%.4f", w.border.mae);
  std::printf(" | %.4f | ", c.border.mae);
  if (all) {
    const double e = overscan_border_error(t, method, preset).mae;
    std::printf("%.4f", e);
    overscan += e / kFrames;
  }
  std::printf(" | %.0f | ", a.ms);
  if (all) std::printf("%.0f", w.ms);
  std::printf(" | %.0f |\n", c.ms);
  for (const shot::Measured* v : {&w, &c})
    EXPECT_LE(v->whole.mae, a.whole.mae * 1.02) << to_string(method) << " " << to_string(preset) << " frame " << t
                                                << (v == &w ? ", t-2..t+2" : ", chosen views");
  whole.alone += a.whole.mae / kFrames, whole.window += w.whole.mae / kFrames, whole.chosen += c.whole.mae / kFrames;
  border.alone += a.border.mae / kFrames, border.window += w.border.mae / kFrames;
  border.chosen += c.border.mae / kFrames;
}

TEST(SequenceAccuracy, SyntheticShotImprovesAndNoFrameGetsWorse) {
  for (const auto& [method, preset] : {std::pair{AoMethod::gtao, Preset::medium}, std::pair{AoMethod::gtao, Preset::high},
                                       std::pair{AoMethod::raymarch, Preset::low}}) {
    std::printf("%s %s: MAE against the ray-traced AO (whole frame, then the border band: %.0f%% of the pixels), "
                "ms of compute per frame\n", std::string(to_string(method)).c_str(),
                std::string(to_string(preset)).c_str(), 100.0 * border_fraction());
    std::printf("| frame | views chosen | alone | t-%d..t+%d | --views %d | border alone | t-%d..t+%d | --views %d | "
                "overscan, alone | ms alone | ms t-%d..t+%d | ms --views %d |\n", kDefaultViewsPerSide,
                kDefaultViewsPerSide, kDefaultViewsPerSide, kDefaultViewsPerSide, kDefaultViewsPerSide,
                kDefaultViewsPerSide, kDefaultViewsPerSide, kDefaultViewsPerSide, kDefaultViewsPerSide);
    ShotMeans whole, border;
    double overscan = 0;
    for (int t = 0; t < kFrames; ++t) measure_frame(t, method, preset, whole, border, overscan);
    const bool all = method != AoMethod::raymarch;
    std::printf("| mean | | %.4f | ", whole.alone);
    if (all) std::printf("%.4f (%+.0f%%)", whole.window, 100.0 * (whole.window / whole.alone - 1.0));
    std::printf(" | %.4f (%+.0f%%) | %.4f | ", whole.chosen, 100.0 * (whole.chosen / whole.alone - 1.0), border.alone);
    if (all) std::printf("%.4f", border.window);
    std::printf(" | %.4f | ", border.chosen);
    if (all) std::printf("%.4f", overscan);
    std::printf(" | | | |\n");
    EXPECT_LE(whole.chosen, whole.alone * (1.0 - kMinMeanGain)) << to_string(method) << " " << to_string(preset);
    if (all) {
      EXPECT_LE(whole.window, whole.alone * (1.0 - kMinMeanGain)) << to_string(method) << " " << to_string(preset);
    }
    EXPECT_LE(border.chosen, border.alone * (1.0 - kMinBorderGain)) << to_string(method) << " " << to_string(preset);
  }
}

// The GTAO presets' thickness from silhouettes against the constant, alone and with the
// service's views, mean over the shot: the silhouettes err less alone than the constant does
// with views, and the views still lower their error (measured: gtao medium 0.0652 constant,
// 0.0556 with views; 0.0545 silhouettes, 0.0514 with views; high 0.0762, 0.0623; 0.0555,
// 0.0528). The views only carve free space out of the estimated layer
// (kernels/half_resolution.cpp, grid_back_layer).
TEST(SequenceAccuracy, SilhouettesAndViewsTogetherErrLeast) {
  for (const Preset preset : {Preset::medium, Preset::high}) {
    double mean[2][2] = {};  // [model][alone, chosen views]
    for (int t = 0; t < kFrames; ++t)
      for (const ThicknessModel model : {ThicknessModel::constant, ThicknessModel::silhouettes}) {
        mean[int(model)][0] += measure(frame_with_views(t, Views::none), t, AoMethod::gtao, preset, model).whole.mae;
        mean[int(model)][1] += measure(frame_with_views(t, Views::chosen), t, AoMethod::gtao, preset, model).whole.mae;
      }
    for (auto& m : mean)
      for (double& v : m) v /= kFrames;
    std::printf("gtao %s, shot mean MAE: constant %.4f, with views %.4f; silhouettes %.4f, with views %.4f\n",
                std::string(to_string(preset)).c_str(), mean[0][0], mean[0][1], mean[1][0], mean[1][1]);
    EXPECT_LT(mean[1][0], mean[0][1]) << to_string(preset);
    EXPECT_LT(mean[1][1], mean[1][0] * 0.98) << to_string(preset);
  }
}

}  // namespace
}  // namespace ssdo
