#include "service/path_policy.h"

#include <climits>
#include <cstdlib>
#include <filesystem>
#include <memory>

namespace ssdo {

namespace fs = std::filesystem;

bool path_is_under(const std::string& path, const std::string& root) {
  if (root.empty() || path.empty()) return false;
  if (root == "/") return path[0] == '/';
  if (path.compare(0, root.size(), root) != 0) return false;
  return path.size() == root.size() || path[root.size()] == '/';
}

bool canonical_path(const std::string& path, std::string& canonical, std::string& error) {
  std::unique_ptr<char, decltype(&std::free)> resolved(::realpath(path.c_str(), nullptr), &std::free);
  if (!resolved) {
    error = path + ": no such file or folder";
    return false;
  }
  canonical = resolved.get();
  return true;
}

bool resolve_allowed_input(const std::string& path, const std::vector<std::string>& roots,
                           std::string& resolved, std::string& error) {
  if (!canonical_path(path, resolved, error)) return false;
  for (const std::string& root : roots)
    if (path_is_under(resolved, root)) return true;
  error = path + ": outside the allowed folders (resolves to " + resolved + "; see --allow)";
  return false;
}

bool resolve_allowed_output(const std::string& path, const std::string& root, std::string& resolved,
                            std::string& error) {
  const fs::path p(path);
  const std::string name = p.filename().string();
  if (name.empty() || name == "." || name == "..") {
    error = path + ": not a file name";
    return false;
  }
  std::string folder;
  if (!canonical_path(p.has_parent_path() ? p.parent_path().string() : ".", folder, error)) {
    error = path + ": its folder does not exist";
    return false;
  }
  if (!path_is_under(folder, root)) {
    error = path + ": outside the output folder " + root;
    return false;
  }
  resolved = (fs::path(folder) / name).string();
  // An existing symlink at the output name could point anywhere: refuse it (the writer
  // renames over the link itself, but a reader of the reply would follow it).
  std::error_code ec;
  if (fs::is_directory(fs::symlink_status(resolved, ec))) {
    error = path + ": is a folder; the output must be a file name";
    return false;
  }
  if (fs::is_symlink(fs::symlink_status(resolved, ec))) {
    error = path + ": the output name is a symbolic link";
    return false;
  }
  return true;
}

}  // namespace ssdo
