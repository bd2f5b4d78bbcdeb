#include "service/frame_list.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <set>
#include <thread>
#include <vector>

#include "formats/camera_io.h"
#include "formats/output_writer.h"
#include "service/file_version.h"
#include "service/pipeline.h"
#include "service/request_options.h"
#include "service/version.h"

namespace ssdo {

namespace fs = std::filesystem;

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

bool has_exr_extension(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  return lower.size() > 4 && ends_with(lower, ".exr");
}

bool is_frame_file(const std::string& path) {
  const std::string name = fs::path(path).filename().string();
  if (name.empty() || name[0] == '.' || !has_exr_extension(name)) return false;
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  return !ends_with(lower, ".ssdo.exr");
}

std::string frame_for_sidecar(const std::string& path) {
  static const std::string suffix = ".camera.json";
  const std::string name = fs::path(path).filename().string();
  if (name.size() <= suffix.size() || name[0] == '.' || !ends_with(name, suffix)) return {};
  const std::string frame = path.substr(0, path.size() - suffix.size()) + ".exr";
  return sidecar_path_for(frame) == path && is_frame_file(frame) ? frame : std::string();
}

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
      // Every frame file but folders, also one that cannot be opened (a dangling link, say):
      // that frame fails with its own reason, and the others are computed. Only the listing
      // itself can fail the folder (its own error code: an entry's does not).
      std::vector<std::string> found;
      for (fs::directory_iterator it(input, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
        std::error_code entry_ec;
        if (!it->is_directory(entry_ec) && is_frame_file(it->path().string())) found.push_back(it->path().string());
      }
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

std::string error_path_for(const std::string& input, const std::string& output_dir) {
  std::string out = output_path_for(input, output_dir);
  out.resize(out.size() - std::string(".ssdo.exr").size());
  return out + ".error.json";
}

std::string error_path_for_output(const std::string& output) {
  const std::string suffix = ".ssdo.exr";
  std::string lower = output;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ends_with(lower, suffix) && lower.size() > suffix.size() && lower[lower.size() - suffix.size() - 1] != '/')
    return output.substr(0, output.size() - suffix.size()) + ".error.json";
  return output + ".error.json";
}

bool output_up_to_date(const std::string& input, const std::string& output) {
  const FileVersion in = version_of(input), out = version_of(output);
  // Only a file is an output made before (a folder in its place fails the frame, by name).
  if (!in.exists || !out.regular) return false;
  return !later_than(in.last_change(), out.mtime);
}

namespace {

// The writer's pid of a temp file of this host: ".NAME.tmp-HOST-PID-RANDOM"
// (formats/output_writer.h), or the older ".NAME.tmp-PID-err" and ".NAME.tmp-PID-client"
// of this host's error files and client downloads. 0 when `name` is none of these.
long temp_file_pid(const std::string& name, const std::string& host) {
  const size_t at = name.rfind(".tmp-");
  if (name.empty() || name[0] != '.' || at == std::string::npos) return 0;
  // Only names of what ssdo writes (outputs, previews, error files, tables): another
  // program's ".notes.tmp-..." in a shared folder is not ours to remove.
  const std::string final_name = name.substr(1, at - 1);
  if (!ends_with(final_name, ".exr") && !ends_with(final_name, ".png") && !ends_with(final_name, ".json") &&
      !ends_with(final_name, ".csv"))
    return 0;
  const std::string rest = name.substr(at + 5);
  const size_t last_dash = rest.rfind('-');
  if (last_dash == std::string::npos || last_dash == 0) return 0;
  std::string pid_text;
  const std::string suffix = rest.substr(last_dash + 1);
  if (suffix == "err" || suffix == "client") {
    pid_text = rest.substr(0, last_dash);
  } else {
    const size_t pid_dash = rest.rfind('-', last_dash - 1);
    if (pid_dash == std::string::npos || rest.substr(0, pid_dash) != host) return 0;
    pid_text = rest.substr(pid_dash + 1, last_dash - pid_dash - 1);
  }
  if (pid_text.empty() || pid_text.find_first_not_of("0123456789") != std::string::npos || pid_text.size() > 9)
    return 0;
  return std::stol(pid_text);
}

}  // namespace

OutputMadeWith output_made_with(const std::string& output, const std::string& options_attribute,
                                const std::string& window_attribute) {
  const ExistingOutput made = read_existing_output(output, {kOptionsAttribute, kVersionAttribute, kWindowAttribute});
  const bool same_window = window_attribute.empty() || made.attributes[2] == window_attribute;
  std::error_code ec;
  auto has_preview = [&](const std::string& channel) {
    return fs::is_regular_file(preview_path(output, channel.substr(0, channel.find('.'))), ec);
  };
  const bool previews = !made.channels.empty() && std::all_of(made.channels.begin(), made.channels.end(), has_preview);
  return {made.attributes[0] == options_attribute && made.attributes[1] == version_string() && same_window,
          made.attributes[0].has_value() && made.attributes[1].has_value(), made.chunks_complete, previews};
}

void remove_output_and_previews(const std::string& output) {
  std::error_code ec;
  fs::remove(output, ec);
  remove_previews_except(output, {});
}

bool output_up_to_date_with_all(const std::vector<std::string>& files, const std::string& output) {
  return std::all_of(files.begin(), files.end(), [&](const std::string& f) { return output_up_to_date(f, output); });
}

FrameFiles frame_files(const std::string& frame) { return {version_of(frame), version_of(sidecar_path_for(frame))}; }

bool changed_since(const std::string& frame, const FrameFiles& found) {
  const FrameFiles now = frame_files(frame);
  return !(now.input == found.input) || !(now.sidecar == found.sidecar);
}

bool mark_out_of_date(const std::string& output, const FrameFiles& found) {
  timespec last{0, 0};
  for (const FileVersion* v : {&found.input, &found.sidecar})
    if (v->exists && later_than(v->last_change(), last)) last = v->last_change();
  // A nanosecond before it: file times come from a coarse clock (a few ms), so a version
  // written in the same tick as the one found has the same time, and the output must be
  // older than that too. A file system with coarser times truncates this down, not up.
  if (last.tv_nsec > 0) {
    --last.tv_nsec;
  } else if (last.tv_sec > 0) {
    --last.tv_sec;
    last.tv_nsec = 999999999;
  }
  const timespec times[2] = {{0, UTIME_OMIT}, last};
  return ::utimensat(AT_FDCWD, output.c_str(), times, 0) == 0;
}

bool output_up_to_date_with_sidecar(const std::string& input, const std::string& output) {
  const std::string sidecar = sidecar_path_for(input);
  struct stat st {};
  return output_up_to_date(input, output) && (::stat(sidecar.c_str(), &st) != 0 || output_up_to_date(sidecar, output));
}

int remove_temp_files_of(const std::string& dir, long pid) {
  const std::string host = temp_file_host();
  int removed = 0;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    std::error_code entry_ec;
    if (temp_file_pid(entry.path().filename().string(), host) == pid && entry.is_regular_file(entry_ec) &&
        fs::remove(entry.path(), entry_ec))
      ++removed;
  }
  return removed;
}

int remove_stale_temp_files(const std::string& dir, double wait_s) {
  // Only this host's files whose process is gone are abandoned: on a farm, another host's
  // temp file in the shared folder belongs to a task still writing it. Subfolders too
  // (explicit outputs may be written there); symbolic links to folders are not followed.
  const std::string host = temp_file_host();
  int removed = 0;
  struct Owned {
    fs::path path;
    pid_t pid;
  };
  std::vector<Owned> owned;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (const long pid = temp_file_pid(it->path().filename().string(), host); pid > 0)
      owned.push_back({it->path(), pid_t(pid)});
  }
  // Each file whose writer is gone (or whose pid is not one) is removed; the others are
  // checked again until wait_s.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  for (;;) {
    std::erase_if(owned, [&](const Owned& o) {
      if (o.pid > 0 && (::kill(o.pid, 0) == 0 || errno != ESRCH)) return false;
      std::error_code rm;
      if (fs::remove(o.path, rm)) ++removed;
      return true;
    });
    if (owned.empty() || std::chrono::steady_clock::now() >= deadline) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return removed;
}

std::vector<std::string> each_file_once(const std::vector<std::string>& files) {
  std::set<std::string> seen;
  std::vector<std::string> once;
  for (const std::string& f : files) {
    std::error_code ec;
    const fs::path absolute = fs::absolute(f, ec);
    if (seen.insert(ec ? f : absolute.lexically_normal().string()).second) once.push_back(f);
  }
  return once;
}

}  // namespace ssdo
