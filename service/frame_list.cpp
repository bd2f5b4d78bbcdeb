#include "service/frame_list.h"

#include <algorithm>
#include <filesystem>

namespace ssdo {

namespace fs = std::filesystem;

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool is_frame_file(const fs::path& p) {
  std::string name = p.filename().string();
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  return ends_with(lower, ".exr") && !ends_with(lower, ".ssdo.exr") && name[0] != '.';
}

}  // namespace

bool expand_inputs(const std::vector<std::string>& inputs, std::vector<std::string>& frames,
                   std::string& error) {
  for (const std::string& input : inputs) {
    std::error_code ec;
    const fs::file_status st = fs::status(input, ec);
    if (ec || !fs::exists(st)) {
      error = input + ": no such file or folder";
      return false;
    }
    if (fs::is_directory(st)) {
      std::vector<std::string> found;
      for (const fs::directory_entry& e : fs::directory_iterator(input, ec))
        if (e.is_regular_file(ec) && is_frame_file(e.path())) found.push_back(e.path().string());
      if (ec) {
        error = input + ": cannot list the folder: " + ec.message();
        return false;
      }
      std::sort(found.begin(), found.end());
      frames.insert(frames.end(), found.begin(), found.end());
    } else {
      frames.push_back(input);
    }
  }
  return true;
}

std::string output_path_for(const std::string& input, const std::string& output_dir) {
  fs::path in(input);
  std::string stem = in.filename().string();
  std::string lower = stem;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ends_with(lower, ".exr")) stem.resize(stem.size() - 4);
  return (fs::path(output_dir) / (stem + ".ssdo.exr")).string();
}

bool output_up_to_date(const std::string& input, const std::string& output) {
  std::error_code ec1, ec2;
  const auto t_out = fs::last_write_time(output, ec1);
  const auto t_in = fs::last_write_time(input, ec2);
  return !ec1 && !ec2 && t_out >= t_in;
}

}  // namespace ssdo
