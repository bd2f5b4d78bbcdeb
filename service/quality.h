// `--quality auto --max-error E`: the fastest AO method and preset whose measured error
// on the calibration set stays under E. The calibration table is what `ssdo bench` writes
// as calibration.csv (method, preset, samples, ms, mae), measured on the reference Cycles
// frames and shipped inside the binary (service/calibration.csv).
#pragma once

#include <string>
#include <vector>

#include "kernels/ao.h"

namespace ssdo {

struct CalibrationEntry {
  AoMethod method = AoMethod::gtao;
  Preset preset = Preset::medium;
  double ms = 0;   // median time per frame at the calibration resolution
  double mae = 0;  // MAE against the ray-traced AO pass
};

// Parses calibration CSV text; false with a message naming the line on error.
bool parse_calibration(const std::string& csv, std::vector<CalibrationEntry>& entries, std::string& error);

// The table shipped with the binary.
const std::vector<CalibrationEntry>& shipped_calibration();

// The fastest entry with mae <= max_error; when none qualifies, the most accurate one and
// `met` = false.
CalibrationEntry choose_quality(const std::vector<CalibrationEntry>& entries, double max_error, bool& met);

// What --quality auto chose for a request, once, where its options are resolved
// (resolve_compute_options): the AO method and preset it computes with, for the --max-error
// asked.
struct QualityChoice {
  CalibrationEntry entry;
  double max_error = 0;
  bool met = false;  // entry.mae <= max_error; false: no entry does, this is the most accurate
};

}  // namespace ssdo
