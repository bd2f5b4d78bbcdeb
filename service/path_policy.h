// Which files a socket request may name: inputs (and the camera / environment files of
// its options) must resolve, after symlinks and "..", under one of the allowed roots;
// outputs under the output folder. Checked on the resolved (realpath) form, component by
// component, so "/data/in/../../etc/passwd" and a symlink pointing out of a root are both
// refused, and "/data/input2" is not under "/data/input".
#pragma once

#include <string>
#include <vector>

namespace ssdo {

// True when `path` is `root` or lies below it; both absolute and normalised.
bool path_is_under(const std::string& path, const std::string& root);

// The canonical form of an existing path (realpath). False with a message otherwise.
bool canonical_path(const std::string& path, std::string& canonical, std::string& error);

// Resolves an existing file and checks it lies under one of `roots` (canonical paths).
// False with a message naming the path when it does not exist or escapes every root.
bool resolve_allowed_input(const std::string& path, const std::vector<std::string>& roots,
                           std::string& resolved, std::string& error);

// Resolves a file that may not exist yet: its folder must exist and resolve under `root`
// (canonical), and its name must not be "." or "..". `resolved` = canonical folder / name.
bool resolve_allowed_output(const std::string& path, const std::string& root, std::string& resolved,
                            std::string& error);

}  // namespace ssdo
