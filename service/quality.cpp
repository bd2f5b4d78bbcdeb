#include "service/quality.h"

#include <sstream>

#include "service/calibration_csv.h"  // generated: kCalibrationCsv

namespace ssdo {

bool parse_calibration(const std::string& csv, std::vector<CalibrationEntry>& entries, std::string& error) {
  entries.clear();
  std::stringstream in(csv);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#' || line.rfind("method,", 0) == 0) continue;
    std::stringstream ss(line);
    std::string method, preset, samples, ms, mae;
    std::getline(ss, method, ',');
    std::getline(ss, preset, ',');
    std::getline(ss, samples, ',');
    std::getline(ss, ms, ',');
    std::getline(ss, mae, ',');
    const auto m = parse_ao_method(method);
    const auto p = parse_preset(preset);
    CalibrationEntry e;
    try {
      e.ms = std::stod(ms);
      e.mae = std::stod(mae);
    } catch (const std::exception&) {
      error = "calibration line " + std::to_string(line_no) + ": ms and mae must be numbers";
      return false;
    }
    if (!m || !p) {
      error = "calibration line " + std::to_string(line_no) + ": unknown method or preset";
      return false;
    }
    e.method = *m;
    e.preset = *p;
    entries.push_back(e);
  }
  if (entries.empty()) {
    error = "the calibration table is empty";
    return false;
  }
  return true;
}

const std::vector<CalibrationEntry>& shipped_calibration() {
  static const std::vector<CalibrationEntry> table = [] {
    std::vector<CalibrationEntry> entries;
    std::string error;
    parse_calibration(kCalibrationCsv, entries, error);
    return entries;
  }();
  return table;
}

CalibrationEntry choose_quality(const std::vector<CalibrationEntry>& entries, double max_error, bool& met) {
  const CalibrationEntry* fastest = nullptr;
  const CalibrationEntry* best = nullptr;
  for (const CalibrationEntry& e : entries) {
    if (e.method == AoMethod::raymarch) continue;  // the oracle is not a production choice
    if (!best || e.mae < best->mae) best = &e;
    if (e.mae <= max_error && (!fastest || e.ms < fastest->ms)) fastest = &e;
  }
  met = fastest != nullptr;
  if (fastest) return *fastest;
  return best ? *best : CalibrationEntry{};
}

}  // namespace ssdo
