// The ssdo subcommands. main.cpp parses the command line (CLI11) into these argument
// structs and calls run_*; each returns the process exit code (0 ok, 1 a frame failed,
// 2 usage error). Thin front ends: parse, call, report.
#pragma once

#include <string>
#include <vector>

#include "formats/gbuffer_reader.h"

namespace ssdo {

struct InfoArgs {
  std::vector<std::string> files;
  bool json = false;
  ReadOptions read;
};
int run_info(const InfoArgs& args);

}  // namespace ssdo
