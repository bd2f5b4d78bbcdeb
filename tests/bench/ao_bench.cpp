// Timings of the screen-space AO methods per preset and of the denoisers, on a G-buffer of
// the Cornell-like reference scene at 640x360 and 1920x1080 (2 threads).
#include <benchmark/benchmark.h>

#include "kernels/ao.h"
#include "kernels/denoise.h"
#include "kernels/raycast.h"

namespace {

const ssdo::GBuffer& frame(int width) {
  static const ssdo::GBuffer small = ssdo::raycast::render_gbuffer(
      ssdo::raycast::cornell_scene(), ssdo::raycast::cornell_camera(640, 360), 2);
  static const ssdo::GBuffer large = ssdo::raycast::render_gbuffer(
      ssdo::raycast::cornell_scene(), ssdo::raycast::cornell_camera(1920, 1080), 2);
  return width == 640 ? small : large;
}

void BM_Ao(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  const auto method = ssdo::AoMethod(state.range(1));
  const auto preset = ssdo::Preset(state.range(2));
  const ssdo::AoSettings s = ssdo::ao_preset(method, preset);
  const ssdo::AoInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, nullptr};
  ssdo::AoOutput out;
  for (auto _ : state) ssdo::compute_ao(in, s, out, {}, 2);
  state.SetLabel(std::string(ssdo::to_string(method)) + " " + std::string(ssdo::to_string(preset)));
}

void BM_Denoise(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  cv::Mat src(g.depth_view.size(), CV_32FC1), dst;
  cv::randu(src, 0.0f, 1.0f);
  for (auto _ : state)
    ssdo::denoise_bilateral(src, g.depth_view, g.normal_view, g.mask, {}, dst, {}, 2);
}

void BM_BoxBlur(benchmark::State& state) {
  const ssdo::GBuffer& g = frame(int(state.range(0)));
  cv::Mat src(g.depth_view.size(), CV_32FC1), dst;
  cv::randu(src, 0.0f, 1.0f);
  for (auto _ : state) ssdo::box_blur_4x4(src, dst, {}, 2);
}

void ao_args(benchmark::internal::Benchmark* b) {
  for (int w : {640, 1920})
    for (int m : {0, 1, 2})
      for (int p : {0, 1, 2, 3}) b->Args({w, m, p});
}

}  // namespace

BENCHMARK(BM_Ao)->Apply(ao_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Denoise)->Arg(640)->Arg(1920)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_BoxBlur)->Arg(640)->Arg(1920)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
