// Command-line options shared by several subcommands (CLI11), and the conversion of the
// typed frame options (frame_options.h) into the request values the pipeline takes.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "formats/gbuffer_reader.h"
#include "service/frame_options.h"
#include "service/pipeline.h"
#include "service/worker_process.h"

namespace ssdo {

// The frame options of `sets` (OptionSet bits) as CLI11 options on `app`, bound to
// `args`: names, help, groups, choices and ranges from the table (frame_options.h).
void add_frame_options(CLI::App& app, FrameOptionArgs& args, int sets = kAllOptionSets);

// What a subcommand's run callback owns: its own arguments and the frame options it takes.
template <class Args>
struct CommandState {
  Args args;
  FrameOptionArgs options;
};

// True when the command line gave the frame option `key` (a table name) to `app`.
bool given(const CLI::App& app, const std::string& key);

// The frame options of a command: its flags over its --config file (`config`, may be
// empty), then every value checked (the environment map's header too) before any work.
// False with a message naming the file and key.
bool frame_options_over_config(const CLI::App& app, const std::string& config, FrameOptionArgs& options,
                               std::string& error);

// What --quality auto chose for a resolved request (request.quality), as one line for the
// user; empty without --quality auto. Printed once by the command (frame_options_over_config),
// not per frame.
std::string quality_choice_note(const FrameRequest& request);
// The preset `request`, resolved from `args`, computes AO (ssdo false: --quality auto's
// choice, else --preset) or SSDO (true: --ssdo-preset, else --preset) with.
std::string effective_preset(const ComputeOptionArgs& args, const FrameRequest& request, bool ssdo);

// Every option of `app` and its subcommands that takes a value refuses an empty one: on the
// command line "" is a script's unset variable (--chunk "$TASK" on a farm), never a choice,
// and would otherwise select the default silently (every frame instead of a chunk). The
// frame options name the default in their message (add_frame_options).
void refuse_empty_values(CLI::App& app);

// Limits of the worker processes (--jobs, --frame-timeout, --memory-limit, --max-pixels).
void add_worker_limits(CLI::App& app, int& jobs, WorkerLimits& limits);

// A duration option's check: a finite number of seconds in [lo, hi] (CLI11's number
// checks let NaN through, which turns a timeout off).
CLI::Validator seconds_in(double lo, double hi);

// Fill the request; on a bad value return false with a message naming the option.
bool resolve_read_options(const ReadOptionArgs& args, ReadOptions& read, std::string& error);
// Also loads the environment map (once) when one is named. build_environment = false:
// only what is known without decoding the map's pixels is checked (check_env_map) and
// request.environment stays null, for a process that only checks options and leaves the
// frames to workers.
bool resolve_compute_options(const ComputeOptionArgs& args, FrameRequest& request, std::string& error,
                             bool build_environment = true);

// "0.25 0.5 1, 1 0.35 0.08" / "0.25:0.5:1,1:0.35:0.08" / "0.25,0.5,1,1,0.35,0.08" / "1,0.2"
// (grey levels) -> top and bottom colours. False with a message on error.
bool parse_sky(const std::string& spec, glm::vec3& top, glm::vec3& bottom, std::string& error);

// "ssdo" | "ssao" | "off" | "ssao+ssdo" or "ambient_ao:0.5,ssdo_direct,ssdo_indirect:2".
bool parse_composite(const std::string& spec, std::vector<WeightedTerm>& terms, std::string& error);

}  // namespace ssdo
