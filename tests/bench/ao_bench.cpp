// Timings of the screen-space AO methods per preset, of SSDO per preset, of the denoisers
// (1 and 3 channels; the frame's 7 at the half grid's footprint), of the confidence term,
// of the temporal filter, of a shot frame's finish and of the whole compute step of a
// frame (`compute_frame`, terms ao,ssdo: AO, SSDO, three denoise passes), at 640x360 (the shared cornell dump) and
// 1920x1080 (the shared perf1080 dump), with 1 and 2 threads. Without ../shared the
// Cornell-like scene of the reference ray caster is rendered at both sizes instead.
// Args: width, method, preset, threads (BM_Ao, BM_AoConstantThickness); width, preset, threads
// (BM_Ssdo, BM_SsdoEnv, BM_Frame); width, threads (denoisers, BM_Confidence, BM_HalfGrid,
// BM_SilhouetteThickness); width, spacing, threads (BM_DenoiseHalfGridTerms); width, images,
// threads (BM_Upsample);
// width, K, threads (BM_Temporal, BM_TemporalMoving, BM_TemporalSsdo); width, K, with SSDO, threads
// (BM_ShotFinish). The thread count is always last (tests/bench/thread_scaling.sh).
#include <benchmark/benchmark.h>

#include <map>
#include <optional>

#include "kernels/ao.h"
#include "kernels/confidence.h"
#include "kernels/denoise.h"
#include "kernels/half_resolution.h"
#include "tests/accuracy/shot_views.h"
#include "tests/bench/bench_frames.h"
#include "tests/support/raycast.h"
#include "kernels/ssdo.h"
#include "kernels/temporal.h"
#include "service/pipeline.h"

namespace {

using ssdo::bench::frame;

// The method's preset on the frame, through compute_ao_at_resolution, with `model` in place
// of the preset's thickness model when given; labelled "METHOD PRESET [MODEL] Nt".
void run_ao(benchmark::State& state, std::optional<ssdo::ThicknessModel> model, const char* model_label) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const auto method = ssdo::AoMethod(state.range(1));
  const auto preset = ssdo::Preset(state.range(2));
  const int threads = int(state.range(3));
  ssdo::AoSettings s = ssdo::ao_preset(method, preset);
  if (model) s.thickness_model = *model;
  const ssdo::AoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, nullptr};
  ssdo::AoOutput out;
  for (auto _ : state) ssdo::compute_ao_at_resolution(in, s, out, {}, threads);
  state.SetLabel(std::string(ssdo::to_string(method)) + " " + std::string(ssdo::to_string(preset)) + model_label +
                 " " + std::to_string(threads) + "t");
}

void BM_Ao(benchmark::State& state) { run_ao(state, std::nullopt, ""); }

// BM_Ao with the constant thickness in place of the preset's model (the GTAO presets
// estimate a back layer from the silhouettes on the grid they run on; BM_SilhouetteThickness).
void BM_AoConstantThickness(benchmark::State& state) { run_ao(state, ssdo::ThicknessModel::constant, " constant"); }

void BM_Denoise(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  cv::Mat src(g.depth_view.size(), CV_32FC1), dst;
  cv::randu(src, 0.0f, 1.0f);
  for (auto _ : state)
    ssdo::denoise_bilateral(src, g.depth_view, g.normal_view, g.mask, {}, dst, {}, int(state.range(1)));
}

void BM_Denoise3(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  cv::Mat src(g.depth_view.size(), CV_32FC3), dst;
  cv::randu(src, 0.0f, 1.0f);
  for (auto _ : state)
    ssdo::denoise_bilateral(src, g.depth_view, g.normal_view, g.mask, {}, dst, {}, int(state.range(1)));
}

// The frame's denoise of AO and both SSDO terms (1 + 3 + 3 channels, one pass) computed on
// the half-resolution grid: the footprint scaled to that grid (radius 8, sigma 5), with taps
// every tap_spacing_px = range(1) pixels (2: the product's, scaled_to_grid; 1: every pixel
// of the footprint). Args: width, spacing, threads.
void BM_DenoiseHalfGridTerms(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  cv::Mat ao(g.depth_view.size(), CV_32FC1), direct(g.depth_view.size(), CV_32FC3),
      indirect(g.depth_view.size(), CV_32FC3);
  for (cv::Mat* m : {&ao, &direct, &indirect}) cv::randu(*m, 0.0f, 1.0f);
  cv::Mat ao_out, direct_out, indirect_out;
  const cv::Mat* srcs[] = {&ao, &direct, &indirect};
  cv::Mat* dsts[] = {&ao_out, &direct_out, &indirect_out};
  ssdo::DenoiseSettings s = ssdo::scaled_to_grid({}, 2);
  s.tap_spacing_px = int(state.range(1));
  for (auto _ : state)
    ssdo::denoise_bilateral(srcs, g.depth_view, g.normal_view, g.mask, s, dsts, {}, int(state.range(2)));
  state.SetLabel("radius " + std::to_string(s.radius_px) + ", spacing " + std::to_string(s.tap_spacing_px));
}

void time_ssdo(benchmark::State& state, const ssdo::Environment& env, const std::string& what) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const auto preset = ssdo::Preset(state.range(1));
  const int threads = int(state.range(2));
  const ssdo::SsdoSettings s = ssdo::ssdo_preset(ssdo::SsdoMethod::ssdo, preset);
  const ssdo::SsdoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, env,
                            g.has_albedo() ? &g.albedo : nullptr, nullptr};
  ssdo::SsdoOutput out;
  for (auto _ : state) ssdo::compute_ssdo_at_resolution(in, s, out, {}, threads);
  state.SetLabel("ssdo " + std::string(ssdo::to_string(preset)) + what + " " + std::to_string(threads) + "t");
}

void BM_Ssdo(benchmark::State& state) {
  static const ssdo::Environment white;  // constant radiance 1, as the pipeline's default
  time_ssdo(state, white, "");
}

// SSDO lit by the frames' world as a map (`--env examples/env_equirect.exr`): the
// filtered radiance of the samples and the irradiance table at each pixel are looked up.
void BM_SsdoEnv(benchmark::State& state) { time_ssdo(state, ssdo::bench::sky_environment(), " --env"); }

// The compute step of `ssdo process --terms ao,ssdo` (no I/O): the default AO method and
// the SSDO method at one preset, each denoised.
void BM_Frame(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const auto preset = ssdo::Preset(state.range(1));
  ssdo::FrameRequest request;
  request.terms = {true, true, false};
  request.ao = ssdo::ao_preset(ssdo::AoSettings{}.method, preset);
  request.ssdo = ssdo::ssdo_preset(ssdo::SsdoMethod::ssdo, preset);
  request.threads = int(state.range(2));
  for (auto _ : state) benchmark::DoNotOptimize(ssdo::compute_frame(g, request));
  state.SetLabel("ao,ssdo " + std::string(ssdo::to_string(preset)) + " " +
                 std::to_string(request.threads) + "t");
}

// The compute step of `ssdo process --terms ao --views K` (no I/O) at the medium preset: 2K
// extra views, each the frame's own depth and camera (a consistent view whose occupancy
// walk runs to the thickness boundary on every pixel, as on a static shot), against K = 0.
// compute_frame of g (with its views), --terms ao at the medium preset, on `threads`.
void time_ao_medium_frame(benchmark::State& state, const ssdo::GBuffer& g, int threads, const std::string& what) {
  ssdo::FrameRequest request;
  request.terms = {true, false, false};
  request.ao = ssdo::ao_preset(ssdo::AoSettings{}.method, ssdo::Preset::medium);
  request.threads = threads;
  for (auto _ : state) benchmark::DoNotOptimize(ssdo::compute_frame(g, request));
  state.SetLabel(what + "ao medium, " + std::to_string(g.views.size()) + " views, " + std::to_string(threads) + "t");
}

void BM_FrameViews(benchmark::State& state) {
  ssdo::GBuffer g = frame(int(state.range(0)));
  for (int i = 0; i < 2 * int(state.range(1)); ++i) g.views.push_back({g.camera, g.depth_view, "copy"});
  time_ao_medium_frame(state, g, int(state.range(2)), "");
}

// The same on a moving camera: the middle frame of the ray caster's trucking shot
// (raycast::truck_shot_scene: occluders enter and leave the picture, hide behind others)
// at width x 9/16, with the frames t-K..t+K as views (neighbours that see past the edges
// and behind the occluders, as in a real shot), against K = 0.
// moving: two boxes in the middle of the picture also slide along +X by kMovingBoxStepWorld
// per frame (things that move in the shot: what the temporal filter's search for changed
// surroundings finds).
constexpr float kMovingBoxStepWorld = 0.1f;
const std::vector<ssdo::GBuffer>& truck_shot(int width, bool moving = false) {
  static std::map<std::pair<int, bool>, std::vector<ssdo::GBuffer>> shots;
  std::vector<ssdo::GBuffer>& shot = shots[{width, moving}];
  if (shot.empty()) {
    for (int t = 0; t < ssdo::raycast::kTruckShotFrames; ++t) {
      ssdo::raycast::Scene scene = ssdo::raycast::truck_shot_scene();
      if (moving)
        for (const size_t i : {1, 6})  // the low box at x = -0.6 and the cube at x = 0.8: on screen
          scene.boxes[i].centre_world.x += kMovingBoxStepWorld * float(t);
      shot.push_back(ssdo::raycast::render_gbuffer(scene, ssdo::raycast::truck_shot_camera(t, width, width * 9 / 16), 2));
    }
  }
  return shot;
}

void BM_ShotViews(benchmark::State& state) {
  const std::vector<ssdo::GBuffer>& shot = truck_shot(int(state.range(0)));
  const int k = int(state.range(1)), middle = ssdo::raycast::kTruckShotFrames / 2;
  ssdo::GBuffer g = shot[size_t(middle)];
  for (int t = middle - k; t <= middle + k; ++t)
    if (t != middle) g.views.push_back({shot[size_t(t)].camera, shot[size_t(t)].depth_view, "f" + std::to_string(t)});
  time_ao_medium_frame(state, g, int(state.range(2)), "truck shot, ");
}

// The same frame with the views `--views K` picks (by parallax among t-3K..t+3K:
// service/view_selection.h): the cost a user of the default K pays.
void BM_ShotChosenViews(benchmark::State& state) {
  const std::vector<ssdo::GBuffer>& shot = truck_shot(int(state.range(0)));
  const ssdo::GBuffer g = ssdo::shot::with_chosen_views(
      ssdo::raycast::kTruckShotFrames / 2, int(state.range(1)), ssdo::raycast::kTruckShotFrames,
      [&](int u) -> const ssdo::GBuffer& { return shot[size_t(u)]; }, [](int u) { return "f" + std::to_string(u); });
  time_ao_medium_frame(state, g, int(state.range(2)), "truck shot, --views " + std::to_string(state.range(1)) + ", ");
}

// The temporal filter (kernels/temporal.h) of the truck shot's middle frame over the K frames
// on each side, of raw terms of the given channel counts (random values: the cost does not
// depend on them): what --temporal K adds to a frame's finish.
void time_temporal(benchmark::State& state, std::initializer_list<int> term_channels, const std::string& terms_label,
                   bool moving = false) {
  const std::vector<ssdo::GBuffer>& shot = truck_shot(int(state.range(0)), moving);
  const int k = int(state.range(1)), threads = int(state.range(2)), middle = ssdo::raycast::kTruckShotFrames / 2;
  std::vector<std::vector<cv::Mat>> raw(shot.size());
  std::vector<std::vector<const cv::Mat*>> terms(shot.size());
  for (size_t t = 0; t < shot.size(); ++t) {
    for (const int channels : term_channels) {
      raw[t].emplace_back(shot[t].depth_view.size(), CV_32FC(channels));
      cv::randu(raw[t].back(), 0.0f, 1.0f);
    }
    for (const cv::Mat& m : raw[t]) terms[t].push_back(&m);
  }
  auto temporal_frame = [&](int t) {
    const ssdo::GBuffer& g = shot[size_t(t)];
    return ssdo::TemporalFrame{g.camera, g.depth_view, g.normal_view, g.mask, terms[size_t(t)]};
  };
  std::vector<ssdo::TemporalFrame> neighbours;
  for (int t = middle - k; t <= middle + k; ++t)
    if (t != middle) neighbours.push_back(temporal_frame(t));
  std::vector<cv::Mat> filtered(term_channels.size());
  std::vector<cv::Mat*> dsts;
  for (cv::Mat& m : filtered) dsts.push_back(&m);
  int64_t changed_px = 0;
  for (auto _ : state) {
    changed_px = 0;
    for (const ssdo::TemporalUse& u : ssdo::filter_temporal(temporal_frame(middle), neighbours, {}, dsts, {}, threads))
      changed_px += u.changed_px;
  }
  state.SetLabel(std::string(moving ? "truck shot with moving boxes" : "truck shot") + ", --temporal " +
                 std::to_string(k) + ", " + terms_label + ", " + std::to_string(threads) + "t, " +
                 std::to_string(changed_px) + " changed px");
}

// AO alone (--terms ao).
void BM_Temporal(benchmark::State& state) { time_temporal(state, {1}, "ao"); }
// The same where the boxes move: every pixel's surroundings are searched for changes.
void BM_TemporalMoving(benchmark::State& state) { time_temporal(state, {1}, "ao", true); }
// AO and the two SSDO terms (--terms ao,ssdo): 7 channels.
void BM_TemporalSsdo(benchmark::State& state) { time_temporal(state, {1, 3, 3}, "ao,ssdo"); }

// A shot frame's finish (service/pipeline.h: finish_frame) over the K frames on each side
// of the truck shot's middle frame, every raw frame computed once outside the timing: the
// temporal filter, the denoise, the upsample of the half grid's terms. range(2): 0 = --terms
// ao, 1 = --terms ao,ssdo (no composite), the medium presets.
void BM_ShotFinish(benchmark::State& state) {
  const std::vector<ssdo::GBuffer>& shot = truck_shot(int(state.range(0)));
  const int k = int(state.range(1)), middle = ssdo::raycast::kTruckShotFrames / 2;
  const bool with_ssdo = state.range(2) != 0;
  ssdo::FrameRequest request;
  request.terms = {true, with_ssdo, false};
  request.ao = ssdo::ao_preset(ssdo::AoSettings{}.method, ssdo::Preset::medium);
  request.ssdo = ssdo::ssdo_preset(ssdo::SsdoMethod::ssdo, ssdo::Preset::medium);
  request.threads = int(state.range(3));
  const ssdo::RawFrame frame = ssdo::compute_raw_frame(ssdo::GBuffer(shot[size_t(middle)]), request);
  std::vector<ssdo::RawFrame> parts;
  for (int t = middle - k; t <= middle + k; ++t)
    if (t != middle) parts.push_back(ssdo::temporal_part(ssdo::compute_raw_frame(ssdo::GBuffer(shot[size_t(t)]), request)));
  std::vector<const ssdo::RawFrame*> neighbours;
  for (const ssdo::RawFrame& p : parts) neighbours.push_back(&p);
  // finish_frame consumes its frame: each run finishes a copy of the image headers (the
  // finish writes new images and releases headers, never the shared pixels).
  for (auto _ : state) benchmark::DoNotOptimize(ssdo::finish_frame(ssdo::RawFrame(frame), neighbours, request));
  state.SetLabel("truck shot, --temporal " + std::to_string(k) + (with_ssdo ? ", ao,ssdo" : ", ao") + " medium, " +
                 std::to_string(request.threads) + "t");
}

// The confidence term at the default settings as the pipeline runs it: on the frame's half
// grid (built once, outside the timing), then upsampled (in a frame, in the one upsample of
// every half-resolution term).
void BM_Confidence(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const int threads = int(state.range(1));
  const ssdo::FullGrid full{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera};
  ssdo::HalfGrid half;
  ssdo::build_half_grid(full, half, threads, /*with_positions=*/false);
  ssdo::ConfidenceSettings s;
  s.max_radius_px = ssdo::max_radius_on_grid(s.max_radius_px, 2);  // as compute_terms gives it
  cv::Mat half_confidence, confidence(g.depth_view.size(), CV_32FC1);
  const ssdo::UpsampleImage images[] = {{half_confidence, confidence, cv::Scalar(1.0), cv::Scalar(1.0)}};
  for (auto _ : state) {
    ssdo::compute_confidence(half.depth_view, half.normal_view, half.mask, half.camera, s, half_confidence, {},
                             threads);
    ssdo::upsample_from_half_grid(full, half, images, cv::Rect(0, 0, g.depth_view.cols, g.depth_view.rows), threads);
  }
  state.SetLabel(std::to_string(threads) + "t");
}

// The half-resolution grid of a frame without positions: each texel's source pixel, depth,
// normal and the view-space position from the depth (what a --terms ao frame builds first).
void BM_HalfGrid(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const int threads = int(state.range(1));
  const ssdo::FullGrid full{g.depth_view, g.normal_view, cv::Mat(), g.mask, g.camera};
  ssdo::HalfGrid half;
  for (auto _ : state) ssdo::build_half_grid(full, half, threads, /*with_positions=*/true);
  state.SetLabel(std::to_string(threads) + "t");
}

// The upsample from the frame's half grid to full resolution of the images of range(1): 0,
// GTAO's AO (clamped) and bent normal (renormalised) in float, as compute_ao_at_resolution
// writes them; 1, a `--terms ao,ssdo` frame's, as the pipeline stores them: those two, SSDO's
// direct and indirect light and the confidence in half floats, the denoised AO, direct and
// indirect in float (18 channels). The texels' values are uniform noise (the weights depend
// on the guides only). Args: width, images, threads.
void BM_Upsample(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const bool whole_frame = state.range(1) == 1;
  const int threads = int(state.range(2));
  const ssdo::FullGrid full{g.depth_view, g.normal_view, cv::Mat(), g.mask, g.camera};
  ssdo::HalfGrid half;
  ssdo::build_half_grid(full, half, threads, /*with_positions=*/false);
  const cv::Size size = g.depth_view.size(), half_size = half.depth_view.size();
  constexpr int kImages = 8;
  cv::Mat texels[kImages], pixels[kImages];
  const int channels[kImages] = {3, 1, 3, 3, 1, 1, 3, 3};
  const bool in_half[kImages] = {whole_frame, whole_frame, true, true, true, false, false, false};
  std::vector<ssdo::UpsampleImage> images;
  for (int i = 0; i < (whole_frame ? kImages : 2); ++i) {
    texels[i].create(half_size, CV_32FC(channels[i]));
    cv::randu(texels[i], i == 0 ? -1.0f : 0.0f, 1.0f);
    pixels[i].create(size, CV_MAKETYPE(in_half[i] ? CV_16F : CV_32F, channels[i]));
    const cv::Scalar fill = channels[i] == 1 ? cv::Scalar(1.0) : cv::Scalar::all(0);
    const ssdo::UpsampleFinish finish = i == 0   ? ssdo::UpsampleFinish::unit_vector
                                        : i == 1 ? ssdo::UpsampleFinish::clamp_unit_interval
                                                 : ssdo::UpsampleFinish::none;
    images.push_back({texels[i], pixels[i], fill, fill, finish});
  }
  const cv::Rect all(cv::Point(), size);
  for (auto _ : state) ssdo::upsample_from_half_grid(full, half, images, all, threads);
  state.SetLabel(std::string(whole_frame ? "ao,ssdo frame" : "gtao") + " " + std::to_string(threads) + "t");
}

// The back layer estimated from the silhouettes of the frame's half grid (what low and
// medium run on when the frame has no back-face pass).
void BM_SilhouetteThickness(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const int threads = int(state.range(1));
  const ssdo::FullGrid full{g.depth_view, g.normal_view, cv::Mat(), g.mask, g.camera};
  ssdo::HalfGrid half;
  ssdo::build_half_grid(full, half, threads, /*with_positions=*/false);
  cv::Mat back;
  for (auto _ : state) ssdo::estimate_back_depth(half.depth_view, half.mask, half.camera, {}, back, threads);
  state.SetLabel(std::to_string(threads) + "t");
}

void BM_BoxBlur(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  cv::Mat src(g.depth_view.size(), CV_32FC1), dst;
  cv::randu(src, 0.0f, 1.0f);
  for (auto _ : state) ssdo::box_blur_4x4(src, dst, {}, int(state.range(1)));
}

void ao_args(benchmark::internal::Benchmark* b) {
  for (int w : {640, 1920})
    for (int m : {0, 1, 2})
      for (int p : {0, 1, 2, 3})
        for (int t : {1, 2}) b->Args({w, m, p, t});
}

void preset_args(benchmark::internal::Benchmark* b) {
  for (int w : {640, 1920})
    for (int p : {0, 1, 2})
      for (int t : {1, 2}) b->Args({w, p, t});
}

void image_args(benchmark::internal::Benchmark* b) {
  for (int w : {640, 1920})
    for (int t : {1, 2}) b->Args({w, t});
}

}  // namespace

BENCHMARK(BM_Ao)->Apply(ao_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_AoConstantThickness)->Apply(ao_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Denoise)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Denoise3)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DenoiseHalfGridTerms)->ArgsProduct({{640, 1920}, {1, 2}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Ssdo)->Apply(preset_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsdoEnv)->Apply(preset_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Frame)->Apply(preset_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FrameViews)->ArgsProduct({{640, 1920}, {0, 1, 2, 3}, {2}})->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK(BM_ShotViews)->ArgsProduct({{1920}, {0, 1, 2}, {2}})->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK(BM_ShotChosenViews)->ArgsProduct({{1920}, {2}, {2}})->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
BENCHMARK(BM_Temporal)->ArgsProduct({{1920}, {1, 2}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_TemporalMoving)->ArgsProduct({{1920}, {2}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_TemporalSsdo)->Args({1920, 2, 2})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ShotFinish)->ArgsProduct({{1920}, {2}, {0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Confidence)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Upsample)->ArgsProduct({{640, 1920}, {0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HalfGrid)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SilhouetteThickness)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_BoxBlur)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
