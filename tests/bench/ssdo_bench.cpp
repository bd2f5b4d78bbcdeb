// Timings of SSDO (direct + indirect) per preset, of building an environment, and of the
// composite, at 640x360 (the shared cornell dump) and 1920x1080 (the shared perf1080 dump),
// with 1 and 2 threads. The environment is the shared env_equirect.exr's procedural sky as
// a 512x256 equirect built in memory (bench_frames.h, sky_environment). Without
// ../shared the Cornell-like scene of the reference ray caster is rendered instead.
// Args: width, preset, threads, sender light (0 = first pass of the kernel, 1 = the frame's
// lighting pass when it has one).
#include <benchmark/benchmark.h>

#include "kernels/half_resolution.h"
#include "kernels/composite.h"
#include "kernels/environment.h"
#include "tests/bench/bench_frames.h"
#include "kernels/ssdo.h"

namespace {

using ssdo::bench::frame;
using ssdo::bench::sky_environment;

void BM_Ssdo(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const auto preset = ssdo::Preset(state.range(1));
  const int threads = int(state.range(2));
  const bool with_lighting = state.range(3) != 0 && !g.lighting.empty();
  const ssdo::SsdoSettings s = ssdo::ssdo_preset(ssdo::SsdoMethod::ssdo, preset);
  const ssdo::SsdoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera,
                            sky_environment(), &g.albedo, with_lighting ? &g.lighting : nullptr};
  ssdo::SsdoOutput out;
  for (auto _ : state) ssdo::compute_ssdo_at_resolution(in, s, out, {}, threads);
  state.SetLabel(std::string(ssdo::to_string(preset)) + " N=" + std::to_string(s.samples) +
                 " k=" + std::to_string(s.sample_steps) + " " + std::to_string(threads) + "t" +
                 (with_lighting ? " lighting" : " own pass"));
}

void BM_EnvironmentBuild(benchmark::State& state) {
  const cv::Mat img = ssdo::bench::sky_equirect();
  for (auto _ : state) benchmark::DoNotOptimize(ssdo::Environment::equirect(img));
}

void BM_Composite(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const cv::Mat light(g.depth_view.size(), CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  const ssdo::CompositeInputs in{g.mask, &g.albedo, nullptr, &light, &light};
  cv::Mat out;
  for (auto _ : state) ssdo::compute_composite(in, {}, out, {}, int(state.range(1)));
}

// The composite as the pipeline runs it without an Env pass: background pixels look up the
// environment along their view ray (asin, atan2 and a bilinear fetch per pixel).
void BM_CompositeEnvironmentBackground(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const cv::Mat light(g.depth_view.size(), CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  const ssdo::CompositeInputs in{g.mask, &g.albedo, nullptr, &light, &light, nullptr, nullptr, &sky_environment(),
                                 &g.camera};
  cv::Mat out;
  for (auto _ : state) ssdo::compute_composite(in, {}, out, {}, int(state.range(1)));
}

void ssdo_args(benchmark::internal::Benchmark* b) {
  for (int w : {640, 1920})
    for (int p : {0, 1, 2, 3})
      for (int t : {1, 2}) b->Args({w, p, t, 0});
  for (int w : {640, 1920}) b->Args({w, 1, 2, 1});
}

void image_args(benchmark::internal::Benchmark* b) {
  for (int w : {640, 1920})
    for (int t : {1, 2}) b->Args({w, t});
}

}  // namespace

BENCHMARK(BM_Ssdo)->Apply(ssdo_args)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_EnvironmentBuild)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Composite)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CompositeEnvironmentBackground)->Apply(image_args)->Unit(benchmark::kMillisecond)->UseRealTime();
