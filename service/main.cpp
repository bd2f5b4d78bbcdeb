// ssdo: screen-space ambient and directional occlusion for G-buffer dumps.
// Parses the command line and hands each subcommand to its run_* function.
#include <iostream>

#include <CLI/CLI.hpp>

#include "service/cli_options.h"
#include "service/commands.h"
#include "service/frame_range.h"
#include "service/request_options.h"
#include "service/version.h"

namespace {

using namespace ssdo;

// True when the command line gave the option named by a schema key.
bool given(const CLI::App& cmd, const std::string& key) {
  const CLI::Option* opt = cmd.get_option_no_throw("--" + key);
  return opt != nullptr && opt->count() > 0;
}

// Output options of the schema (request_options.h) on a command.
void add_output_options(CLI::App& cmd, FrameOptionArgs& o) {
  cmd.add_flag("--png", o.png, "Also write an sRGB PNG preview per term");
  cmd.add_option("--compression", o.compression,
                 "EXR compression: zip (deflate level 1), zips, piz, rle, none (all lossless); dwaa (lossy, files of "
                 "colour terms only)")
      ->check(CLI::IsMember({"zip", "zips", "piz", "rle", "none", "dwaa"}))
      ->capture_default_str();
  cmd.add_flag("--io-only", o.io_only,
               "Benchmark the I/O floor: read and write what the terms would, with stand-in images, computing nothing");
}

// The frame options of a command: its flags over its --config file.
bool frame_options(const CLI::App& cmd, const std::string& config, FrameOptionArgs& options, std::string& error) {
  if (!config.empty()) {
    nlohmann::json j;
    if (!load_json_file(config, j, error)) return false;
    if (!apply_json(j, options, error, [&](const std::string& key) { return given(cmd, key); })) {
      error = config + ": " + error;
      return false;
    }
  }
  // Every value checked (the environment map's header too) before any work; the workers
  // read and build what they compute with.
  FrameRequest check;
  return resolve_frame_options(options, check, error, /*build_environment=*/false);
}

// Limits of the worker processes (memory, time, image size).
void add_worker_limits(CLI::App& cmd, int& jobs, WorkerLimits& limits) {
  cmd.add_option("-j,--jobs", jobs,
                 "Worker processes = frames computed at once, each with cores/jobs threads (0 = "
                 "process: 1 worker with every core; serve: one worker per core)")
      ->check(CLI::Range(0, 256))
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
  cmd.add_option("--frame-timeout", limits.frame_timeout_s,
                 "Seconds a frame may take (read + compute + write) before its worker is killed")
      ->check(CLI::PositiveNumber)
      ->capture_default_str()
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
  cmd.add_option("--memory-limit", limits.memory_limit_mb, "Address-space limit of each worker, MiB")
      ->check(CLI::Range(int64_t(256), int64_t(1) << 22))
      ->capture_default_str()
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
  cmd.add_option("--max-pixels", limits.max_pixels, "Largest frame (width x height) a worker decodes")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 34))
      ->capture_default_str()
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
}

}  // namespace

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
      "  ssdo serve --watch in/ -o out/ --socket /tmp/ssdo.sock   a service (see README)\n"
      "  ssdo client --socket /tmp/ssdo.sock process in/f.exr\n"
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
  std::string process_config;
  process_cmd->add_option("--config", process_config,
                          "JSON file of options: the long flag names without '--' as keys, e.g. "
                          "{\"method\": \"hbao\", \"terms\": \"all\"}; flags given override it")
      ->check(CLI::ExistingFile);
  add_output_options(*process_cmd, process.options);
  process_cmd->add_flag("-v,--verbose", process.verbose,
                        "Per-stage timings (read, compute, write, isolation) and the worker plan");
  add_read_options(*process_cmd, process.options.read);
  add_compute_options(*process_cmd, process.options.compute, true);
  add_worker_limits(*process_cmd, process.jobs, process.limits);
  std::string process_shot_frames;  // --frames outside the shot are dropped (farm overshoot)
  process_cmd->add_option("--shot-frames", process_shot_frames,
                          "The shot's frames, e.g. 1-240: --frames outside them are dropped (a farm's "
                          "last task may ask for frames past the shot's end); a missing frame inside "
                          "them still fails");

  // serve
  ServeArgs serve;
  std::string serve_config;
  CLI::App* serve_cmd = app.add_subcommand(
      "serve", "Run as a service: compute every frame dropped into --watch (and those already there "
               "without output) and answer requests on --socket; SIGTERM/SIGINT stop it gracefully");
  serve_cmd->add_option("--watch", serve.watch_dir, "Folder to watch for frames (*.exr)")->check(CLI::ExistingDirectory);
  serve_cmd->add_option("-o,--out", serve.out_dir, "Output folder: NAME.ssdo.exr, or NAME.error.json")->required();
  serve_cmd->add_option("--poll", serve.poll_s,
                        "Also rescan --watch every SECONDS (network file systems, where inotify sees nothing)")
      ->check(CLI::NonNegativeNumber);
  serve_cmd->add_option("--socket", serve.socket_path, "Unix domain socket to serve requests on");
  serve_cmd->add_option("--socket-mode", serve.socket_mode, "Permissions of the socket (octal)")->capture_default_str();
  serve_cmd->add_option("--allow", serve.allow,
                        "Folder socket requests may read frames (and camera/environment files) from; "
                        "repeatable (default: the --watch folder)")
      ->check(CLI::ExistingDirectory);
  serve_cmd->add_option("--queue", serve.queue_capacity, "Socket requests waiting at most; beyond: busy")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  serve_cmd->add_option("--max-clients", serve.max_clients, "Socket connections at once; beyond: busy")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  serve_cmd->add_option("--client-timeout", serve.client_timeout_s,
                        "Seconds a client has to send a whole request (inline frame included) or take a reply")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  serve_cmd->add_option("--max-request-bytes", serve.protocol.max_header_bytes, "Largest JSON request header")
      ->check(CLI::Range(size_t(64), size_t(1) << 30))
      ->capture_default_str();
  size_t max_inline_mb = serve.protocol.max_inline_bytes >> 20;
  serve_cmd->add_option("--max-inline-mb", max_inline_mb, "Largest inline frame, MiB")
      ->check(CLI::Range(size_t(1), size_t(1) << 16))
      ->capture_default_str();
  serve_cmd->add_option("--config", serve_config, "JSON file of frame options (as for process)")->check(CLI::ExistingFile);
  add_output_options(*serve_cmd, serve.options);
  add_read_options(*serve_cmd, serve.options.read);
  add_compute_options(*serve_cmd, serve.options.compute, true);
  add_worker_limits(*serve_cmd, serve.jobs, serve.limits);

  // client
  ClientArgs client;
  FrameOptionArgs client_options;
  CLI::App* client_cmd = app.add_subcommand(
      "client", "Talk to a running 'ssdo serve --socket': ping, stats, or process FILE... (one JSON "
                "response per line)");
  client_cmd->add_option("--socket", client.socket_path, "The service's socket")->required();
  client_cmd->add_option("action", client.action, "ping, stats or process")
      ->required()
      ->check(CLI::IsMember({"ping", "stats", "process"}));
  client_cmd->add_option("files", client.files, "process: frames (paths the service may read, or sent with --inline)");
  client_cmd->add_flag("--inline", client.inline_data,
                       "Send the frames' bytes (and NAME.camera.json) and receive the outputs' bytes");
  client_cmd->add_option("-o,--out", client.out_dir, "--inline: folder for the outputs")->capture_default_str();
  client_cmd->add_option("--timeout", client.timeout_s, "Seconds to wait for each response")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  add_output_options(*client_cmd, client_options);
  add_read_options(*client_cmd, client_options.read);
  add_compute_options(*client_cmd, client_options.compute, true);

  // worker (internal: started by process and serve)
  WorkerArgs worker;
  CLI::App* worker_cmd = app.add_subcommand("worker", "Internal: a frame worker process")->group("");
  worker_cmd->add_option("--threads", worker.threads)->check(CLI::Range(1, 1024));
  worker_cmd->add_option("--memory-limit", worker.memory_limit_mb);
  worker_cmd->add_option("--max-pixels", worker.max_pixels);
  worker_cmd->add_option("--parent", worker.parent_pid);

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
  eval_cmd->add_option("--against-oracle", eval.oracle_preset,
                       "Compare with the screen-space oracle at this preset (raymarch for AO, the "
                       "SSDO oracle for light terms; same radius and thickness) instead of a pass: "
                       "the method's estimator error alone")
      ->check(CLI::IsMember({"low", "medium", "high", "ultra"}));
  eval_cmd->add_flag("--json", eval.json, "Print JSON");
  eval_cmd->add_option("--heatmap", eval.heatmap_dir, "Write an error image per file into DIR");
  add_read_options(*eval_cmd, eval_read);
  add_compute_options(*eval_cmd, eval_compute, true);

  // bench
  BenchArgs bench;
  ReadOptionArgs bench_read;
  std::vector<std::string> bench_methods;
  bool bench_no_sweep = false;
  CLI::App* bench_cmd = app.add_subcommand(
      "bench", "Run every AO method x preset (and a sweep of sample counts) on frames with a "
               "reference pass; write bench.csv (method, preset, samples, resolution, median ms, "
               "MAE, RMSE, bias, p95), calibration.csv (for --quality auto) and bench.png (error "
               "against time, log time axis)");
  bench_cmd->add_option("files", bench.files, "EXR frames holding the reference pass")->required();
  bench_cmd->add_option("--reference", bench.reference, "Reference pass name")->capture_default_str();
  bench_cmd->add_option("-o,--out", bench.output_dir, "Output folder")->required();
  bench_cmd->add_option("--runs", bench.runs, "Runs per configuration (median time)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  bench_cmd->add_option("--methods", bench_methods,
                        "Methods to run (default hemisphere hbao gtao; raymarch is minutes per frame)")
      ->check(CLI::IsMember({"hemisphere", "hbao", "gtao", "raymarch"}));
  bench_cmd->add_flag("--no-sweep", bench_no_sweep, "Presets only, no sample-count sweep");
  bench_cmd->add_option("--external", bench.external_csv,
                        "CSV of an external reference's cost (series,label,ms,mae), e.g. a ray "
                        "tracer at several sample counts, plotted beside the methods")
      ->check(CLI::ExistingFile);
  bench_cmd->add_option("--threads", bench.request.threads, "Threads for the kernels (0 = all cores)")
      ->check(CLI::Range(0, 1024));
  add_read_options(*bench_cmd, bench_read);

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
    if (!frame_options(*process_cmd, process_config, process.options, error)) return usage_error(error);
    if (!process_shot_frames.empty()) {
      if (process.frames.empty()) return usage_error("--shot-frames needs --frames");
      std::string clipped;
      size_t dropped = 0;
      if (!clip_frame_ranges(process.frames, process_shot_frames, clipped, error, &dropped))
        return usage_error("--frames " + process.frames + " --shot-frames " + process_shot_frames + ": " + error);
      if (dropped > 0)
        std::cerr << "ssdo process: --frames " << process.frames << " within the shot's frames "
                  << process_shot_frames << ": " << (clipped.empty() ? "none, nothing to do" : clipped) << "\n";
      if (clipped.empty()) return 0;
      process.frames = clipped;
    }
    return run_process(process);
  }
  if (*serve_cmd) {
    serve.protocol.max_inline_bytes = max_inline_mb << 20;
    if (!frame_options(*serve_cmd, serve_config, serve.options, error)) return usage_error(error);
    return run_serve(serve);
  }
  if (*client_cmd) {
    client.options = to_json(client_options, [&](const std::string& key) { return given(*client_cmd, key); });
    return run_client(client);
  }
  if (*worker_cmd) return run_worker(worker);
  if (*bench_cmd) {
    if (!resolve_read_options(bench_read, bench.request.read, error)) return usage_error(error);
    if (!bench_methods.empty()) {
      bench.methods.clear();
      for (const std::string& m : bench_methods) bench.methods.push_back(*parse_ao_method(m));
    }
    bench.sweep = !bench_no_sweep;
    return run_bench(bench);
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
