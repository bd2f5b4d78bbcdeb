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
  // SSDO and the environment
  std::string ssdo_method = "ssdo";
  std::string ssdo_preset;        // empty = --preset
  std::string env_path;           // equirect radiance map
  std::string sky;                // "TOP,BOTTOM" two-colour sky
  float env_constant = 0;         // uniform radiance (0 = unset)
  std::string env_up = "z";
  std::string composite;          // mode or weighted term list
  // --quality auto --max-error E: method and preset from the shipped calibration table
  std::string quality;            // "" (method/preset as given) or "auto"
  float max_error = 0.05f;        // MAE against ray-traced AO, for --quality auto
};

void add_read_options(CLI::App& app, ReadOptionArgs& args);
void add_compute_options(CLI::App& app, ComputeOptionArgs& args, bool with_terms);

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
