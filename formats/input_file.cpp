#include "formats/input_file.h"

#include <filesystem>

namespace ssdo {

std::string input_file_error(const std::string& path, const std::string& what, std::uintmax_t max_bytes) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  const std::string named = what.empty() ? path : what + " " + path;
  if (status.type() == fs::file_type::not_found) return named + ": no such file";
  if (ec) return named + ": " + ec.message();
  if (status.type() == fs::file_type::directory) return named + ": a folder, not a file";
  if (status.type() != fs::file_type::regular)
    return named + ": not a regular file (a FIFO, socket or device is refused)";
  const std::uintmax_t bytes = fs::file_size(path, ec);
  if (ec) return named + ": " + ec.message();
  if (bytes > max_bytes)
    return named + ": " + std::to_string(bytes) + " bytes, more than the " + std::to_string(max_bytes) +
           " a " + (what.empty() ? std::string("file") : what) + " may have";
  return {};
}

}  // namespace ssdo
