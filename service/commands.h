// The ssdo subcommands. Each registers its options on the application (register_*,
// beside its run_* in cmd_*.cpp), which parses the command line (CLI11) into its argument
// struct; run_* returns the process exit code (0 ok, 1 a frame failed, 2 usage error).
// Thin front ends: parse, call, report.
#pragma once

#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "formats/gbuffer_reader.h"

namespace CLI {
class App;
}

namespace ssdo {

// A registered subcommand: its CLI11 app, and what runs when the command line chose it
// (the run owns the parsed arguments).
struct Command {
  CLI::App* app;
  std::function<int()> run;
};
Command register_info(CLI::App& app);
Command register_process(CLI::App& app);
Command register_serve(CLI::App& app);
Command register_client(CLI::App& app);
Command register_worker(CLI::App& app);  // internal: started by process and serve
Command register_eval(CLI::App& app);
Command register_bench(CLI::App& app);
Command register_options(CLI::App& app);  // the frame options, e.g. as docs/options.md

// A usage error: the message on stderr, exit code 2.
inline int usage_error(const std::string& message) {
  std::cerr << "ssdo: " << message << "\n";
  return 2;
}

struct InfoArgs {
  std::vector<std::string> files;
  bool json = false;
  ReadOptions read;
};
int run_info(const InfoArgs& args);

}  // namespace ssdo

#include "service/pipeline.h"
#include "service/request_options.h"
#include "service/worker_process.h"

namespace ssdo {

struct ProcessArgs {
  std::vector<std::string> inputs;  // files, folders and frame patterns (shot.####.exr)
  std::string frames;               // --frames "1-100x2,200": numbers for the patterns
  std::string chunk;                // --chunk "I/N": the I-th of N slices of the frame list
  // --shot-frames: the whole shot's numbers. The patterns' frames of the shot are the
  // sequence every frame of this task takes its neighbours from (views and temporal
  // filtering), as in a run of the whole shot; empty = the task's frames are the sequence.
  std::string shot_frames;
  std::string output_dir;
  FrameOptionArgs options;          // every frame's options (checked by the caller)
  bool force = false;               // recompute frames whose output is up to date
  bool verbose = false;             // per-stage timings per frame
  int jobs = 0;                     // worker processes (frames in parallel); 0 = one, with every core
  WorkerLimits limits;              // memory and time per frame (threads: from the plan)
};
int run_process(const ProcessArgs& args);

struct EvalArgs {
  std::vector<std::string> files;
  // Reference channel/pass name in the frame; empty = the term's Cycles pass (AO, DiffDir, DiffInd).
  std::string reference;
  std::string preset = "high";      // preset name, for the report
  std::string term = "ao";          // ao | ssdo_direct | ssdo_indirect (denoised output compared)
  bool raw = false;                 // compare the raw term instead of the denoised one
  // Compare with the screen-space oracle (raymarch for AO, the SSDO oracle for light
  // terms) run on the same frame with the same radius and thickness, instead of a pass:
  // the estimator's own error, apart from what the screen lacks. Empty = use the pass.
  std::string oracle_preset;
  FrameRequest request;             // method, preset, read options
  bool json = false;
  std::string heatmap_dir;
};
int run_eval(const EvalArgs& args);

}  // namespace ssdo

#include "service/protocol.h"

namespace ssdo {

struct ServeArgs {
  std::string watch_dir;             // --watch: frames dropped here are processed
  std::string out_dir;               // --out: OUT/NAME.ssdo.exr, OUT/NAME.error.json
  std::string socket_path;           // --socket: Unix domain socket for requests
  std::string socket_mode = "0600";  // its permissions (octal)
  std::vector<std::string> allow;    // --allow: roots socket requests may read from (default: --watch)
  double poll_s = 0;                 // --poll: also rescan the watch folder every N s (0 = off)
  FrameOptionArgs options;           // options of watched frames; defaults of socket requests
  int jobs = 0;                      // worker processes; 0 = one per core
  WorkerLimits limits;
  size_t queue_capacity = 64;        // socket requests waiting; beyond: "busy"
  int max_clients = 64;              // socket connections at once
  double client_timeout_s = 30;      // to send a whole request / receive a reply
  int retries = 2;                   // new attempts of a frame after a transient failure
  size_t max_spool_mb = 2048;        // inline frames in the spool, all requests together
  ProtocolLimits protocol;
};
int run_serve(const ServeArgs& args);

struct ClientArgs {
  std::string socket_path;
  std::string action;                // ping | stats | process
  std::vector<std::string> files;    // process: input frames
  bool inline_data = false;          // send the EXR bytes and receive the output's bytes
  std::string out_dir = ".";         // --inline: where outputs are written
  nlohmann::json options = nlohmann::json::object();  // only the flags given
  double timeout_s = 600;            // per request, queueing included
  size_t max_inline_mb = 2048;       // --inline: largest output accepted back (held in memory)
};
int run_client(const ClientArgs& args);

struct BenchArgs {
  std::vector<std::string> files;
  std::string reference = "AO";
  std::string output_dir;
  int runs = 3;                      // runs per configuration; the median time is reported
  std::vector<AoMethod> methods = {AoMethod::hemisphere, AoMethod::hbao, AoMethod::gtao};
  bool sweep = true;                 // also sweep sample counts at full resolution
  std::string external_csv;          // external reference costs: series,label,ms,mae
  FrameRequest request;              // read options, threads
  int temporal = 0;                  // > 0: also each preset with --temporal K over the files' sequences
  int views = 0;                     // > 0: also each preset with --views K over the files' sequences
};
int run_bench(const BenchArgs& args);

}  // namespace ssdo
