#include "tests/bench/bench_frames.h"

#include <filesystem>

#include "formats/gbuffer_reader.h"
#include "service/frame_inputs.h"
#include "kernels/positions.h"
#include "tests/support/raycast.h"

namespace ssdo::bench {
namespace {

GBuffer load(int width) {
  const std::filesystem::path dir = std::filesystem::path(SSDO_SHARED_DIR) / "gbuffers";
  const std::filesystem::path file = dir / (width == 640 ? "cornell.exr" : "perf1080.exr");
  if (std::filesystem::exists(file)) {
    ReadOptions options;
    options.read_references = false;
    ReadResult r = read_frame(file.string(), options);
    if (r.ok()) {
      GBuffer g = std::move(r.gbuffer);
      if (g.position_view.empty()) view_positions_from_depth(g.depth_view, g.mask, g.camera, g.position_view);
      return g;
    }
  }
  const int height = width * 9 / 16;
  return raycast::render_gbuffer(raycast::cornell_scene(), raycast::cornell_camera(width, height), 2);
}

}  // namespace

const GBuffer& frame(int width) {
  static const GBuffer small = load(640);
  static const GBuffer large = load(1920);
  return width == 640 ? small : large;
}

}  // namespace ssdo::bench
