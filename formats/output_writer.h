// Writing a frame's results: one multi-channel EXR (named channels, temp file + rename),
// and optional tonemapped sRGB PNG previews.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/resource_failure.h"
#include "formats/camera_io.h"

namespace ssdo {

enum class SampleType { half, float32 };

// One output term: CV_32FC1 (channel "<name>") or CV_32FC3 (channels "<name>.R/G/B", or
// "<name>.X/Y/Z" when `vector` is set, e.g. a bent normal). A term of type half may also be
// given as CV_16FC1 / CV_16FC3 samples already rounded (half_samples::to_half, the bits the
// writer would store): a finished term kept in half takes half the memory until it is
// written.
struct OutputTerm {
  std::string name;     // "ao", "bent_normal", "ssdo_direct", "composite", ...
  cv::Mat image;
  SampleType type = SampleType::half;
  bool vector = false;  // components named X, Y, Z instead of R, G, B
};

// Compression of the output EXR (one part, so one codec for every channel). Numeric terms
// (AO, confidence: float) and vector terms (bent normals) are always stored losslessly:
// "dwaa" (lossy) is refused when a file holds any of them and is meant for files of
// colour terms only. zip and zips deflate at level kFastZipLevel (OpenEXR's default is 4):
// on rendered terms, level 1 writes markedly faster for a file only a few percent larger.
// rle and none write faster still, for files much larger than zip's. The same level means
// the same to both zip encoders (ChunkEncoder) and is checked against zlib's range.
inline constexpr int kFastZipLevel = 1;

// Who packs (and deflates) the chunks of zip, zips and none files. Both write files any
// OpenEXR reader decodes to the same values; only the compressed bytes differ.
enum class ChunkEncoder {
  // The writer packs the chunks itself, converting to half with the CPU's half
  // conversions where it has them (core/half_samples.h), and deflates zip and zips chunks
  // with ISA-L at level 1, libdeflate above (formats/exr_zip: both faster than zlib), on
  // the thread pool; OpenEXRCore writes the header and the chunks.
  own,
  // OpenEXR's own writer (Imf::OutputFile, zlib), as every other compression uses.
  openexr,
};

struct WriteOptions {
  std::string compression = "zip";  // zip | zips | piz | rle | none (dwaa: colour terms only)
  int zip_level = kFastZipLevel;    // deflate level of zip / zips, [1, 9]
  ChunkEncoder chunk_encoder = ChunkEncoder::own;  // zip, zips and none only
  bool png_previews = false;        // NAME.<term>.png beside the EXR
  // Further string attributes of the header, (name, UTF-8 value), e.g. the producing
  // program's version and options ("ssdo/version", "ssdo/options"), so a file found later
  // says how it was made. Names must not be those the writer sets itself (the required
  // attributes, worldToCamera, worldToNDC, clipNear, clipFar).
  std::vector<std::pair<std::string, std::string>> string_attributes;
  // Where the terms' pixel grid sits in absolute EXR pixels (the input frame's data window
  // origin) and the display window it belongs to (empty: the grid itself). The output keeps
  // both, so that a crop's or an overscan frame's terms land where its pixels do; its
  // worldToNDC is then over the display window, as OpenEXR defines it.
  int data_x = 0, data_y = 0;
  std::optional<PixelBox> display_window;
  // Threads that convert and compress: 0 = OpenEXR's global pool and OpenCV's pool as
  // configured; 1 = serial in the calling thread; N = N threads. ChunkEncoder::own packs
  // and compresses chunks on OpenCV's pool (parallel_rows) only.
  int threads = 0;
};

// This host's name as it appears in temp file names (".NAME.tmp-<host>-<pid>-<random>"):
// letters, digits, '.' and '_' only, followed by its kernel's boot and PID namespace, so that
// a pid is only ever tested where it means the same process (frame_list.h,
// remove_stale_temp_files): not in another container, nor on another machine of the same
// name.
std::string temp_file_host();

// A temp file ".NAME.tmp-<host>-<pid>-<random>" beside `final_path`, created with
// O_CREAT | O_EXCL | O_NOFOLLOW (open(2)): always a new regular file of this process, never
// an existing file or a symbolic link planted at the name. The descriptor stays open while
// the file is written; a writer that opens by name uses write_name() ("/proc/self/fd/N",
// proc(5): the same file, whatever happens to the folder's names meanwhile).
class TempFile {
 public:
  TempFile() = default;
  ~TempFile();  // closes; removes the file unless it was committed
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  // False with a message naming the folder.
  bool create(const std::filesystem::path& final_path, std::string& error);
  std::string write_name() const { return "/proc/self/fd/" + std::to_string(fd_); }
  int fd() const { return fd_; }
  const std::filesystem::path& path() const { return path_; }
  // Renames the temp file onto `final_path` (rename(2): atomic in one folder); on failure
  // removes it and returns a message naming `final_path`.
  std::string commit(const std::filesystem::path& final_path);

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  bool committed_ = false;
};

// Writes `bytes` to `path` through a TempFile and rename: complete or absent. Empty on
// success, else a message naming `path`.
std::string write_file_atomically(const std::filesystem::path& path, const std::string& bytes);

// The string attribute `name` of the first part of the EXR at `path` (what write_outputs
// wrote with options.string_attributes); nullopt when the file cannot be read, its headers
// fail check_exr_headers, or it has no such string attribute.
std::optional<std::string> read_string_attribute(const std::string& path, const std::string& name);
// The same for several names, from one read of the headers (in the order of `names`).
std::vector<std::optional<std::string>> read_string_attributes(const std::string& path,
                                                               const std::vector<std::string>& names);

// The PNG preview of term `term` of the output EXR at `output` (WriteOptions::png_previews):
// OUT/NAME.ssdo.<term>.png beside OUT/NAME.ssdo.exr; the term a file is named after gives
// the file's own name (OUT/NAME.error.png for the term "error" of OUT/NAME.error.exr, not
// NAME.error.error.png).
std::string preview_path(const std::string& output, const std::string& term);

// What an existing output says of itself, from one open of the EXR at `path`.
struct ExistingOutput {
  // The string attributes asked for, as read_string_attributes gives them.
  std::vector<std::optional<std::string>> attributes;
  // Whether every scanline chunk lies within the file (what write_outputs writes is
  // scanline): false for a file cut short (an interrupted copy, a crash after the rename,
  // before the data reached the disk) or that cannot be read. Read from the headers, the
  // offset tables and each chunk's leader, not the pixels.
  bool chunks_complete = false;
  // The channel names of its first part (empty when it cannot be read).
  std::vector<std::string> channels;
};
ExistingOutput read_existing_output(const std::string& path, const std::vector<std::string>& names);

// Writes all terms into one scanline EXR at `path`: written as ".NAME.tmp-<host>-<pid>-<rnd>"
// in the same folder and renamed into place, so the file is complete or absent (on failure
// the temp file is removed and an existing `path` is left as it was). All terms must share
// one size, equal to the camera grid when camera.width_px > 0. Compression "dwaa" is lossy
// and refused for 1-channel (numeric) and vector terms.
// The camera is carried over as worldToCamera (OpenEXR convention: camera looks down +Z,
// i.e. our view space with z negated) and worldToNDC (display window = the terms' grid),
// plus float attributes clipNear / clipFar when known: read_gbuffer reads them back; then
// options.string_attributes, in their order.
// png_previews: preview_path's files beside the EXR, 8-bit, clamped to [0, 1]
// and sRGB-encoded; vector terms are shown as 0.5 v + 0.5 without sRGB encoding (the usual
// normal-map colours). Previews are written through temp files too.
// Returns an empty string on success, else the error (naming the file).
std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options = {});
// The same, and whether its failure was memory or a thread running out (`exhausted`; none on
// success and for any other failure).
std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options, ResourceFailure& exhausted);

}  // namespace ssdo
