// ssdo: screen-space ambient and directional occlusion for G-buffer dumps.
// Each subcommand registers its options (cmd_*.cpp); main parses and runs the one chosen.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/simd.h"
#include "service/cli_options.h"
#include "service/commands.h"
#include "service/version.h"

int main(int argc, char** argv) {
  using namespace ssdo;
  CLI::App app{
      "ssdo turns G-buffer dumps (EXR with depth, optionally normals, positions, albedo and light\n"
      "passes, plus a camera) into screen-space ambient occlusion (hemisphere SSAO, HBAO, GTAO),\n"
      "screen-space directional occlusion and edge-aware denoised, composited images.",
      "ssdo"};
  // SSDO_SIMD=baseline: the kernels' fallback instead of the best instruction set this CPU
  // runs (core/simd.h); workers inherit it.
  if (std::string error; !apply_simd_choice(std::getenv("SSDO_SIMD"), error)) {
    std::fprintf(stderr, "ssdo: %s\n", error.c_str());
    return 2;
  }
  app.set_version_flag("--version", std::string(version_string()) + " (kernels: " + simd_target() +
                                        "; compiled for " + simd_targets_compiled() + ")");
  app.require_subcommand(1);
  app.footer(
      "Examples:\n"
      "  ssdo info frame.exr                         what the frame holds and how it will be read\n"
      "  ssdo process frames/ -o out/                AO + composite for every frame in a folder\n"
      "  ssdo process f.exr -o out/ --terms all --env sky.exr\n"
      "  ssdo serve --watch in/ -o out/ --socket /tmp/ssdo.sock   a service (docs/service.md)\n"
      "  ssdo client --socket /tmp/ssdo.sock process in/f.exr\n"
      "  ssdo eval f.exr --reference AO --method gtao --preset high\n"
      "  ssdo eval f.exr --term ssdo_direct --reference DiffDir --env sky.exr\n"
      "Camera: a NAME.camera.json sidecar, the EXR attributes worldToCamera + worldToNDC, or --fov.\n"
      "Run 'ssdo COMMAND --help' for a command's options; 'ssdo options' lists the frame options.");

  const Command commands[] = {register_info(app),   register_process(app), register_serve(app),
                              register_client(app), register_worker(app),  register_eval(app),
                              register_bench(app),  register_options(app)};
  refuse_empty_values(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every other parse error is a usage error (2).
    return app.exit(e) == 0 ? 0 : 2;
  }
  for (const Command& c : commands)
    if (c.app->parsed()) return c.run();
  return 2;
}
