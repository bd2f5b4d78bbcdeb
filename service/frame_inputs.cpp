#include "service/frame_inputs.h"

#include <exception>
#include <string>

#include "kernels/normals.h"
#include "kernels/positions.h"

namespace ssdo {

namespace {

void complete_normals(GBuffer& g, FrameInfo& info, int threads) {
  if (!g.has_normals()) {
    reconstruct_normals_from_depth(g.depth_view, g.mask, g.camera, g.normal_view, {}, threads);
    info.normals_reconstructed = true;
    return;
  }
  if (g.normal_missing.empty()) return;
  cv::Mat rebuilt;
  reconstruct_normals_from_depth(g.depth_view, g.mask, g.camera, rebuilt, {}, threads);
  rebuilt.copyTo(g.normal_view, g.normal_missing);
  g.normal_missing.release();
  info.notes.push_back(std::to_string(info.repaired_normal_pixels) +
                       " foreground pixels had a zero normal: reconstructed from depth");
}

void complete_positions(GBuffer& g, FrameInfo& info, int threads) {
  if (!info.positions_missing || !g.position_view.empty()) return;
  view_positions_from_depth(g.depth_view, g.mask, g.camera, g.position_view, {}, threads);
  info.uses.push_back({"position", "computed from depth", "view"});
}

}  // namespace

void complete_gbuffer(ReadResult& frame, int threads) {
  if (!frame.ok()) return;
  try {
    complete_normals(frame.gbuffer, frame.info, threads);
    complete_positions(frame.gbuffer, frame.info, threads);
    return;
  } catch (const std::exception& e) {
    frame.error = frame.info.path + ": " + e.what();
    frame.exhausted = resource_failure(e);
  } catch (...) {
    frame.error = frame.info.path + ": unknown error while reading";
  }
  frame.gbuffer = GBuffer{};
}

ReadResult read_frame(const std::string& path, const ReadOptions& options) {
  ReadResult frame = read_gbuffer(path, options);
  complete_gbuffer(frame, options.threads);
  return frame;
}

}  // namespace ssdo
