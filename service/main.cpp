// ssdo: screen-space ambient and directional occlusion for G-buffer dumps.
// Parses the command line and hands each subcommand to its run_* function.
#include <iostream>

#include <CLI/CLI.hpp>

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
  app.set_version_flag("--version", version_string());
  app.require_subcommand(1);
  app.footer(
      "Examples:\n"
      "  ssdo info frame.exr                         what the frame holds and how it will be read\n"
      "  ssdo process frames/ -o out/                AO + composite for every frame in a folder\n"
      "  ssdo process f.exr -o out/ --terms all --env sky.exr\n"
      "  ssdo eval f.exr --reference AO --method gtao --preset high\n"
      "  ssdo eval f.exr --term ssdo_direct --reference DiffDir --env sky.exr\n"
      "Camera: a NAME.camera.json sidecar, the EXR attributes worldToCamera + worldToNDC, or --fov.\n"
      "Run 'ssdo COMMAND --help' for a command's options.");

  // info
  InfoArgs info;
  ReadOptionArgs info_read;
  CLI::App* info_cmd = app.add_subcommand(
      "info", "Print what a frame holds: resolution, parts, channels, detected profile, which "
              "channel becomes which input, camera and its source, depth range, masked pixels");
  info_cmd->add_option("files", info.files, "EXR frames")->required();
  info_cmd->add_flag("--json", info.json, "Print JSON instead of text");
  add_read_options(*info_cmd, info_read);

  // process
  ProcessArgs process;
  ReadOptionArgs process_read;
  ComputeOptionArgs process_compute;
  CLI::App* process_cmd = app.add_subcommand(
      "process", "Compute the selected terms for frames and write one EXR per frame "
                 "(OUT/NAME.ssdo.exr). Frames whose output is newer than the input are skipped.");
  process_cmd
      ->add_option("inputs", process.inputs,
                   "EXR frames, folders of frames, or frame patterns (shot.####.exr, shot.%04d.exr) "
                   "with --frames")
      ->required();
  process_cmd->add_option("--frames", process.frames,
                          "Frame numbers for patterns, oiiotool-style: 1-100, 1-100x2, 1-10,20,30");
  process_cmd->add_option("--chunk", process.chunk,
                          "Process only the I-th of N equal slices of the frame list (I/N, I from 1): "
                          "one task of a farm job");
  process_cmd->add_option("-o,--out", process.output_dir, "Output folder")->required();
  process_cmd->add_flag("--force", process.force, "Recompute frames whose output is up to date");
  process_cmd->add_flag("--png", process.request.write.png_previews,
                        "Also write an sRGB PNG preview per term");
  process_cmd->add_option("--compression", process.request.write.compression,
                          "EXR compression: zip, zips, piz, none; dwaa (colour terms only)")
      ->check(CLI::IsMember({"zip", "zips", "piz", "none", "dwaa"}))
      ->capture_default_str();
  process_cmd->add_flag("-v,--verbose", process.verbose, "Per-stage timings (read, compute, write)");
  add_read_options(*process_cmd, process_read);
  add_compute_options(*process_cmd, process_compute, true);

  // eval
  EvalArgs eval;
  ReadOptionArgs eval_read;
  ComputeOptionArgs eval_compute;
  eval_compute.preset = "high";
  CLI::App* eval_cmd = app.add_subcommand(
      "eval", "Compare computed AO with a reference pass of the same frame (e.g. Cycles' "
              "ray-traced AO) over foreground pixels: MAE, RMSE, bias, 95th percentile, time");
  eval_cmd->add_option("files", eval.files, "EXR frames holding the reference pass")->required();
  eval_cmd->add_option("--reference", eval.reference, "Reference pass name (AO for Cycles dumps)")
      ->capture_default_str();
  eval_cmd->add_option("--term", eval.term,
                       "Term to compare: ao (with --reference AO), ssdo_direct (--reference DiffDir) "
                       "or ssdo_indirect (--reference DiffInd)")
      ->check(CLI::IsMember({"ao", "ssdo_direct", "ssdo_indirect"}))
      ->capture_default_str();
  eval_cmd->add_flag("--raw", eval.raw, "Compare the raw term instead of the denoised one");
  eval_cmd->add_flag("--json", eval.json, "Print JSON");
  eval_cmd->add_option("--heatmap", eval.heatmap_dir, "Write an error image per file into DIR");
  add_read_options(*eval_cmd, eval_read);
  add_compute_options(*eval_cmd, eval_compute, true);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every other parse error is a usage error (2).
    return app.exit(e) == 0 ? 0 : 2;
  }

  std::string error;
  auto usage_error = [&](const std::string& msg) {
    std::cerr << "ssdo: " << msg << "\n";
    return 2;
  };
  if (*info_cmd) {
    if (!resolve_read_options(info_read, info.read, error)) return usage_error(error);
    return run_info(info);
  }
  if (*process_cmd) {
    if (!resolve_read_options(process_read, process.request.read, error) ||
        !resolve_compute_options(process_compute, process.request, error))
      return usage_error(error);
    return run_process(process);
  }
  if (*eval_cmd) {
    if (!resolve_read_options(eval_read, eval.request.read, error) ||
        !resolve_compute_options(eval_compute, eval.request, error))
      return usage_error(error);
    eval.request.terms = {eval.term == "ao", eval.term != "ao", false};
    eval.radius_from_frame = eval_compute.radius_world <= 0;
    eval.preset = eval_compute.preset;
    return run_eval(eval);
  }
  return 2;
}
