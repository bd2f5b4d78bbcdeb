// Command-line options shared by several subcommands (CLI11), and their conversion
// into the request values the pipeline takes.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "formats/gbuffer_reader.h"
#include "service/pipeline.h"

namespace ssdo {

// Raw option values as typed; resolved into a request by resolve_*.
struct ReadOptionArgs {
  std::vector<std::string> maps;  // --map input=channel
  std::string camera_json;
  float fov_x_deg = 0;
  std::string depth_kind = "auto";
  std::string part;
};

struct ComputeOptionArgs {
  std::string method = "gtao";
  std::string preset = "medium";
  float radius_world = 0;  // 0 = preset / frame default
  float thickness_world = 0;
  int threads = 0;
  std::string terms = "ao,composite";
};

void add_read_options(CLI::App& app, ReadOptionArgs& args);
void add_compute_options(CLI::App& app, ComputeOptionArgs& args, bool with_terms);

// Fill the request; on a bad value return false with a message naming the option.
bool resolve_read_options(const ReadOptionArgs& args, ReadOptions& read, std::string& error);
bool resolve_compute_options(const ComputeOptionArgs& args, FrameRequest& request, std::string& error);

}  // namespace ssdo
