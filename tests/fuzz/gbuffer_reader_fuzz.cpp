// libFuzzer target: arbitrary bytes as an EXR file through the whole read_gbuffer path
// (OpenEXR header and pixel decoding, profile detection, camera attributes, depth
// conventions, masks, normal conversion) and its completion (service/frame_inputs.h:
// normals and positions reconstructed from depth).
//
// The reader promises never to throw and to report every failure as a message; the
// target checks that promise and the shape of a successful result. The options vary
// with the input's length so one corpus covers several reading modes without shifting
// the bytes of the seed files.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "formats/gbuffer_reader.h"
#include "service/frame_inputs.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ssdo::fuzz::MemFile file(data, size);
  ssdo::ReadOptions options;
  // Far below the service's limits (64 Mpixel) so one input stays fast and within the
  // fuzzer's memory budget; the guards themselves (formats/exr_header_check.h) are what
  // is exercised: 64 Kpixel blocks, 4 MiB of decoded channels.
  options.max_pixels = int64_t(1) << 16;
  options.max_decoded_bytes = int64_t(1) << 22;
  options.threads = 1;  // deterministic, and a hang is a hang of this input
  switch (size % 4) {
    case 0: options.fov_x_deg = 60.0f; break;  // a camera for files without one
    case 1: options.fov_x_deg = 45.0f; options.depth_kind = ssdo::DepthKind::radial; break;
    case 2: options.read_positions = true; options.fov_x_deg = 90.0f; break;
    case 3: break;  // no camera unless the file has one
  }
  const ssdo::ReadResult header = ssdo::inspect_gbuffer(file.path(), options);
  ssdo::ReadResult r = ssdo::read_frame(file.path(), options);
  if (r.ok()) {
    const ssdo::GBuffer& g = r.gbuffer;
    // A successful read is a consistent G-buffer of the data window's size.
    if (g.depth_view.rows != r.info.height_px || g.depth_view.cols != r.info.width_px) std::abort();
    if (!g.mask.empty() && g.mask.size() != g.depth_view.size()) std::abort();
    if (g.normal_view.size() != g.depth_view.size() || !g.normal_missing.empty()) std::abort();
    if (options.read_positions && g.position_view.size() != g.depth_view.size()) std::abort();
  }
  (void)header;
  return 0;
}
