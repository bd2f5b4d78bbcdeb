// Writes the seed corpora of the fuzz targets: small valid inputs of every kind each
// parser accepts, plus a few near misses. Usage: ssdo_fuzz_seeds OUT_DIR
// (creates OUT_DIR/<target>/ for each target of tests/fuzz/).
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "service/protocol.h"
#include "tests/fuzz/seed_exr.h"

namespace fs = std::filesystem;

namespace {

bool write_file(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
  return bool(out);
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string framed(const std::string& body) {
  unsigned char prefix[4];
  ssdo::encode_length(uint32_t(body.size()), prefix);
  return std::string(reinterpret_cast<const char*>(prefix), 4) + body;
}

// A camera sidecar as Blender dumps write it (tests/../gbuffers/README.md), 8 x 6.
const char* kSidecar = R"({"width": 8, "height": 6,
 "world_to_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,-3],[0,0,0,1]],
 "projection": [[1.3,0,0,0],[0,1.73,0,0],[0,0,-1.0001,-0.1],[0,0,-1,0]],
 "clip_near": 0.05, "clip_far": 1000.0, "ao_distance": 1.0,
 "normal_space": "world", "position_space": "world", "depth_kind": "planar",
 "background_depth": 10000000000.0})";

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  const fs::path out = argv[1];
  bool ok = true;
  auto seed = [&](const std::string& target, const std::string& name, const std::string& bytes) {
    fs::create_directories(out / target);
    ok = write_file(out / target / name, bytes) && ok;
  };

  // G-buffer reader: one file per variant.
  fs::create_directories(out / "gbuffer_reader");
  std::vector<std::string> exr(ssdo::fuzz::kSeedExrVariants);
  for (int v = 0; v < ssdo::fuzz::kSeedExrVariants; ++v) {
    const fs::path p = out / "gbuffer_reader" / ("variant" + std::to_string(v) + ".exr");
    ok = ssdo::fuzz::write_seed_exr(p.string(), v) && ok;
    exr[size_t(v)] = read_file(p);
  }

  // Sidecars and option files.
  seed("json_options", "sidecar.json", kSidecar);
  seed("json_options", "sidecar_radial_view.json",
       R"({"width": 8, "height": 6, "world_to_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],)"
       R"( "projection": [[1,0,0,0],[0,1.33,0,0],[0,0,-1,-0.2],[0,0,-1,0]], "depth_kind": "radial",)"
       R"( "normal_space": "camera", "position_space": "view"})");
  seed("json_options", "sidecar_ortho.json",
       R"({"width": 16, "height": 12, "world_to_camera": [[0,0,1,0],[0,1,0,0],[-1,0,0,2],[0,0,0,1]],)"
       R"( "projection": [[0.5,0,0,0],[0,0.66,0,0],[0,0,-0.02,-1.0],[0,0,0,1]]})");
  seed("json_options", "config_full.json",
       R"({"map": ["depth=Z", "normal=N", "normal-space=world", "ref:AO=AO.R"], "fov": 60, "depth-kind": "planar",)"
       R"( "part": "", "method": "gtao", "preset": "low", "radius": 0.5, "thickness": 0.25, "threads": 1,)"
       R"( "terms": "ao,ssdo,composite", "ssdo-method": "ssdo", "ssdo-preset": "low", "sky": "0.25:0.5:1,1:0.35:0.08",)"
       R"( "env-up": "z", "composite": "ambient_ao:0.5,ssdo_direct,ssdo_indirect:2", "compression": "zip", "png": false})");
  seed("json_options", "config_small.json", R"({"method": "hbao", "preset": "low", "terms": "ao"})");
  seed("json_options", "config_map.json",
       R"({"map": "depth=ViewLayer.Depth.Z", "method": "hemisphere", "preset": "low", "env-constant": 2, "composite": "ssao"})");
  seed("json_options", "config_raymarch.json", R"({"method": "raymarch", "preset": "low", "terms": "all", "env-up": "y"})");

  // Socket streams: one or more framed requests, some with inline bytes.
  const std::string root = "/tmp/ssdo-fuzz-socket/in";
  seed("socket_request", "ping", framed(R"({"op": "ping", "id": 1})"));
  seed("socket_request", "stats_ping", framed(R"({"op": "stats"})") + framed(R"({"op": "ping", "id": "x"})"));
  seed("socket_request", "process_path",
       framed(R"({"op": "process", "id": 7, "input": ")" + root + R"(/frame.exr", "options": {"method": "gtao", "preset": "low", "png": true}})"));
  seed("socket_request", "process_escape",
       framed(R"({"op": "process", "input": ")" + root + R"(/escape.exr"})") +
           framed(R"({"op": "process", "input": ")" + root + R"(/../../../etc/passwd"})"));
  seed("socket_request", "process_output",
       framed(R"({"op": "process", "input": ")" + root + R"(/frame.exr", "output": "/tmp/x.exr"})"));
  seed("socket_request", "process_camera",
       framed(R"({"op": "process", "input": ")" + root + R"(/frame.exr", "options": {"camera": ")" + root +
              R"(/camera.json", "env": ")" + root + R"(/etc/hostname"}})"));
  const std::string small = exr[1];
  seed("socket_request", "process_inline",
       framed(R"({"op": "process", "id": [1, 2], "inline_size": )" + std::to_string(small.size()) +
              R"(, "name": "shot.0001", "sidecar": )" + kSidecar + R"(, "reply": "inline"})") +
           small + framed(R"({"op": "ping"})"));
  seed("socket_request", "inline_short",
       framed(R"({"op": "process", "inline_size": 100000, "name": "a"})") + small);
  seed("socket_request", "too_large", std::string("\x7f\xff\xff\xff{\"op\":\"ping\"}", 17));
  seed("socket_request", "bad_json", framed(R"({"op": "ping")") + framed("[1,2]"));

  // Frame ranges: spec, shot, pattern, chunk (one per line).
  seed("frame_range", "basic", "1-100x2,200\n1-150\nshot.####.exr\n2/8");
  seed("frame_range", "negative", "-5--1,3,10-4x3\n-10-10\nrender/%04d.exr\n1/1");
  seed("frame_range", "at", "1001-1240\n1001-1200\nplate.@@@@@.exr\n24/24");
  seed("frame_range", "single", "7\n7\nframe.#.exr\n1/3");
  seed("frame_range", "extremes", "-2147483648,2147483647\n-2147483648-2147483647x2147483647\n%d\n3/2");

  // CLI values: --map entries, --sky, --composite, --terms.
  seed("cli_values", "maps", "depth=Z\nnormal=N\nposition=P\nalbedo=albedo\nlighting=DiffDir\nnormal-space=view\nref:AO=AO.R");
  seed("cli_values", "sky", "0.25 0.5 1, 1 0.35 0.08\n0.25:0.5:1,1:0.35:0.08\n0.25,0.5,1,1,0.35,0.08\n1,0.2");
  seed("cli_values", "composite", "ssdo\nssao\noff\nssao+ssdo\nambient_ao:0.5,ssdo_direct,ssdo_indirect:2\nlighting:16,ambient:0");
  seed("cli_values", "terms", "ao\nao,ssdo\nall\ncomposite,ao\n,,ao,");

  if (!ok) std::fprintf(stderr, "ssdo_fuzz_seeds: could not write every seed under %s\n", argv[1]);
  return ok ? 0 : 1;
}
