// The first check of every file a command line names (a frame, a camera sidecar, an
// environment map, a CSV): it exists and is a regular file, after symbolic links, of at
// most a given size. A FIFO would block the reader forever and a device such as /dev/zero
// would feed it without end; both are refused before anything opens them.
#pragma once

#include <cstdint>
#include <string>

namespace ssdo {

// No limit on the size: the reader's own limits (pixels, decoded bytes) apply.
inline constexpr std::uintmax_t kAnyFileSize = UINTMAX_MAX;
// JSON and CSV files a person writes: a camera sidecar is ~1 KB.
inline constexpr std::uintmax_t kMaxTextFileBytes = 16u << 20;

// Empty when `path` is a regular file of at most `max_bytes`; else the reason, naming
// `path` and `what` ("camera sidecar", "environment map").
std::string input_file_error(const std::string& path, const std::string& what,
                             std::uintmax_t max_bytes = kAnyFileSize);

}  // namespace ssdo
