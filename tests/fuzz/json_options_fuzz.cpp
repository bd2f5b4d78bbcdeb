// libFuzzer target: arbitrary bytes as
// - a camera sidecar (read_camera_sidecar), and when it parses, the camera of a small
//   valid G-buffer read through read_gbuffer (so the sidecar's matrices, size, depth
//   kind, spaces and background value reach the conversion code);
// - a JSON options file (--config: load_json_file, apply_json) and the options it
//   names, resolved as the pipeline resolves them (channel mapping, methods, presets,
//   terms, sky, composite), then used to read the same G-buffer and compute its terms.
// Checks: nothing throws or crashes, and options survive their own round trip
// (to_json then apply_json gives the same JSON).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include <nlohmann/json.hpp>

#include "formats/camera_io.h"
#include "formats/gbuffer_reader.h"
#include "service/frame_inputs.h"
#include "service/pipeline.h"
#include "service/request_options.h"
#include "tests/fuzz/fuzz_util.h"
#include "tests/fuzz/seed_exr.h"

namespace {

// Variant 0 (Blender profile with header camera) and 1 (generic, half, cropped).
std::string g_exr[2];

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  for (int i = 0; i < 2; ++i) {
    char name[] = "/tmp/ssdo-fuzz-json-XXXXXX";
    const int fd = ::mkstemp(name);
    if (fd < 0) std::abort();
    ::close(fd);
    g_exr[i] = name;
    if (!ssdo::fuzz::write_seed_exr(g_exr[i], i)) std::abort();
  }
  std::atexit([] {
    for (const std::string& p : g_exr) ::unlink(p.c_str());
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ssdo::fuzz::MemFile file(data, size);
  const std::string& exr = g_exr[size % 2];

  // As a camera sidecar.
  std::string error;
  if (ssdo::read_camera_sidecar(file.path(), &error)) {
    ssdo::ReadOptions read;
    read.camera_json = file.path();
    read.threads = 1;
    (void)ssdo::read_gbuffer(exr, read);
  } else if (error.empty()) {
    std::abort();  // a refusal always says why
  }

  // As a JSON options file.
  nlohmann::json j;
  error.clear();
  if (!ssdo::load_json_file(file.path(), j, error)) return 0;
  ssdo::FrameOptionArgs args;
  if (!ssdo::apply_json(j, args, error)) return 0;
  // Round trip: what was accepted is written back and read again unchanged.
  const nlohmann::json written = ssdo::to_json(args);
  ssdo::FrameOptionArgs again;
  std::string error2;
  if (!ssdo::apply_json(written, again, error2) || ssdo::to_json(again) != written) std::abort();
  // Files named by options are the path policy's concern (service/path_policy.h); the
  // target does not open arbitrary paths.
  args.read.camera_json.clear();
  args.compute.env_path.clear();
  ssdo::FrameRequest request;
  if (!ssdo::resolve_frame_options(args, request, error)) return 0;
  request.read.threads = 1;
  if (!request.read.fov_x_deg) request.read.fov_x_deg = 50.0f;
  request.threads = 1;
  ssdo::ReadResult frame = ssdo::read_frame(exr, request.read);
  // The settings the boundary accepted, on the kernels (an 8 x 6 frame: cheap).
  if (frame.ok()) (void)ssdo::compute_frame(frame.gbuffer, request);
  return 0;
}
