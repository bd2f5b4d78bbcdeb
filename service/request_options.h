// One schema for a frame's options, shared by the command line, the JSON config file
// (--config), the worker requests and the socket requests: the keys are the long flag
// names without "--" and the values are what the flag takes, e.g.
//   {"method": "gtao", "preset": "high", "terms": "ao,ssdo", "map": ["depth=Z"], "png": true}
// The keys, types and ranges are the table frame_options() (frame_options.h; listed in
// docs/options.md).
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/cli_options.h"

namespace ssdo {

// The schema's keys, in the table's order.
const std::vector<std::string>& frame_option_keys();

// Every key with its value; with `given`, only the keys it returns true for.
nlohmann::json to_json(const FrameOptionArgs& args);
nlohmann::json to_json(const FrameOptionArgs& args, const std::function<bool(const std::string& key)>& given);

// Sets the keys present in `j` (an object) on `args`, except those `keep` returns true
// for (flags given on the command line win over a config file). Checks types and the
// value sets the command line checks; an unknown key is an error. False with a message
// naming the key.
bool apply_json(const nlohmann::json& j, FrameOptionArgs& args, std::string& error,
                const std::function<bool(const std::string& key)>& keep = {});

// Reads a JSON object from a file. False with a message naming the file (and the line
// of a syntax error).
bool load_json_file(const std::string& path, nlohmann::json& j, std::string& error);

// Turns typed options into a request (resolve_read_options + resolve_compute_options +
// write options): loads and builds the environment map when one is named (only checks
// its header when build_environment is false, see resolve_compute_options).
bool resolve_frame_options(const FrameOptionArgs& args, FrameRequest& request, std::string& error,
                           bool build_environment = true);

// Header attributes of an output EXR that say how it was made: kVersionAttribute holds
// version_string() ("ssdo 0.1.0"), kOptionsAttribute the frame options as one JSON object
// (to_json's keys and values, all but "threads"). docs/usage.md, "What a file says about itself".
inline constexpr const char* kVersionAttribute = "ssdo/version";
inline constexpr const char* kOptionsAttribute = "ssdo/options";
// The neighbouring frames an output of a shot was made with (sequence.h, window_attribute):
// a rerun whose window holds other frames (one deleted, one rendered since, a wider
// --shot-frames, a window the memory limit narrowed) computes the frame again.
inline constexpr const char* kWindowAttribute = "ssdo/window";
std::vector<std::pair<std::string, std::string>> output_attributes(const FrameOptionArgs& args);
// The kOptionsAttribute value of outputs made with `args`.
std::string options_attribute(const FrameOptionArgs& args);

// The paths an options object names (camera, env): the service checks them against its
// allowed roots before a worker opens them.
std::vector<std::string> option_paths(const FrameOptionArgs& args);

}  // namespace ssdo
