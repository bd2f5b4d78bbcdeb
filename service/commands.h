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

#include "service/pipeline.h"

namespace ssdo {

struct ProcessArgs {
  std::vector<std::string> inputs;  // files, folders and frame patterns (shot.####.exr)
  std::string frames;               // --frames "1-100x2,200": numbers for the patterns
  std::string chunk;                // --chunk "I/N": the I-th of N slices of the frame list
  std::string output_dir;
  FrameRequest request;             // template: input/output paths filled per frame
  bool force = false;               // recompute frames whose output is up to date
  bool verbose = false;             // per-stage timings per frame
};
int run_process(const ProcessArgs& args);

struct EvalArgs {
  std::vector<std::string> files;
  std::string reference = "AO";     // reference channel/pass name in the frame
  std::string preset = "high";      // preset name, for the report
  std::string term = "ao";          // ao | ssdo_direct | ssdo_indirect (denoised output compared)
  bool raw = false;                 // compare the raw term instead of the denoised one
  FrameRequest request;             // method, preset, read options
  bool radius_from_frame = true;    // AO radius from the frame's sidecar when known
  bool json = false;
  std::string heatmap_dir;
};
int run_eval(const EvalArgs& args);

}  // namespace ssdo
