// Frame I/O kernels: reading a frame (depth, normals, albedo, lighting) with each ZIP
// decoder, and writing its 21 output channels (AO, SSDO and composite terms: 3 float, 18
// half) with each chunk encoder, zip or uncompressed, with 1 and 2 threads. The frame is the
// shared 1080p Cycles dump (perf1080.exr, 26 channels, ZIP). Without ../shared the
// benchmarks report an error.
// Args: decoder or encoder (0 = libdeflate / own, 1 = openexr), threads; for writing also
// the compression (0 = zip, 1 = none).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <unistd.h>

#include "formats/gbuffer_reader.h"
#include "service/frame_inputs.h"
#include "formats/output_writer.h"
#include "service/pipeline.h"

namespace {

namespace fs = std::filesystem;

const fs::path kFrame = fs::path(SSDO_SHARED_DIR) / "gbuffers" / "perf1080.exr";

ssdo::ReadOptions read_options(int decoder, int threads) {
  ssdo::ReadOptions options;
  options.read_references = false;
  options.zip_decoder = decoder == 0 ? ssdo::ZipDecoder::libdeflate : ssdo::ZipDecoder::openexr;
  options.threads = threads;
  return options;
}

void BM_ReadFrame(benchmark::State& state) {
  if (!fs::exists(kFrame)) {
    state.SkipWithError(("no frame at " + kFrame.string()).c_str());
    return;
  }
  const ssdo::ReadOptions options = read_options(int(state.range(0)), int(state.range(1)));
  for (auto _ : state) {
    ssdo::ReadResult r = ssdo::read_frame(kFrame.string(), options);
    if (!r.ok()) {
      state.SkipWithError(r.error.c_str());
      return;
    }
    benchmark::DoNotOptimize(r.gbuffer.depth_view.data);
  }
}
BENCHMARK(BM_ReadFrame)->ArgsProduct({{0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_WriteTerms(benchmark::State& state) {
  if (!fs::exists(kFrame)) {
    state.SkipWithError(("no frame at " + kFrame.string()).c_str());
    return;
  }
  ssdo::ReadResult r = ssdo::read_frame(kFrame.string(), read_options(0, 2));
  if (!r.ok()) {
    state.SkipWithError(r.error.c_str());
    return;
  }
  // The frame's real terms (AO, SSDO and the composite at the low presets, under a constant
  // sky): the noisy float and half channels are what decides the codecs' speed and sizes.
  const ssdo::GBuffer& g = r.gbuffer;
  ssdo::FrameRequest request;
  request.terms.ao = request.terms.ssdo = request.terms.composite = true;
  request.ao = ssdo::ao_preset(ssdo::AoMethod::gtao, ssdo::Preset::low);
  request.ssdo = ssdo::ssdo_preset(ssdo::SsdoMethod::ssdo, ssdo::Preset::low);
  request.threads = 2;
  const std::vector<ssdo::OutputTerm> terms = ssdo::compute_frame(g, request).terms;
  ssdo::WriteOptions options;
  options.chunk_encoder = state.range(0) == 0 ? ssdo::ChunkEncoder::own : ssdo::ChunkEncoder::openexr;
  options.threads = int(state.range(1));
  options.compression = state.range(2) == 0 ? "zip" : "none";
  const fs::path out = fs::temp_directory_path() / ("ssdo_io_bench_" + std::to_string(::getpid()) + ".exr");
  for (auto _ : state) {
    const std::string error = ssdo::write_outputs(out.string(), terms, g.camera, options);
    if (!error.empty()) {
      state.SkipWithError(error.c_str());
      break;
    }
  }
  std::error_code ec;
  state.counters["MB"] = double(fs::file_size(out, ec)) / 1e6;
  fs::remove(out, ec);
}
BENCHMARK(BM_WriteTerms)->ArgsProduct({{0, 1}, {1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
