#include "formats/output_writer.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cctype>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <span>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/openexr.h>
#include <Imath/half.h>

#include "formats/camera_io.h"
#include "formats/exr_core.h"
#include "formats/exr_header_check.h"
#include "formats/exr_zip.h"
#include "core/sample_planes.h"
#include "core/half_samples.h"
#include "formats/png_file.h"
#include "core/parallel.h"

namespace ssdo {

namespace {

// What tells this process's pids from another's that shares the host name: the kernel's
// boot (its random boot id: another machine, or this one after a reboot) and the PID
// namespace (another container on this kernel), as "_BOOT_NS" in hex; empty where /proc
// does not say.
std::string pid_space_tag() {
  std::string boot;
  std::ifstream("/proc/sys/kernel/random/boot_id") >> boot;
  boot.erase(std::remove(boot.begin(), boot.end(), '-'), boot.end());
  struct stat ns {};
  if (boot.size() < 8 || ::stat("/proc/self/ns/pid", &ns) != 0) return {};
  std::ostringstream tag;
  tag << "_" << boot.substr(0, 8) << "_" << std::hex << uint64_t(ns.st_ino);
  return tag.str();
}

}  // namespace

std::string temp_file_host() {
  static const std::string host = [] {
    char name[256] = {};
    std::string h = ::gethostname(name, sizeof name - 1) != 0 || name[0] == '\0' ? "localhost" : name;
    // Only characters that cannot be confused with the name's separators.
    for (char& c : h)
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_') c = '_';
    return h + pid_space_tag();
  }();
  return host;
}

namespace {

// ".NAME.tmp-<host>-<pid>-<random>" beside the final file: same file system, so rename()
// is atomic, and hidden, so watchers of the folder skip it. The host name lets a task on a
// render farm that shares the output folder tell its own host's abandoned temp files
// (dead pid) from another host's files in progress (service/frame_list.h). A NAME too long
// for that within a file name's 255 bytes keeps its end (the extension the cleanup
// recognises) behind a '~'.
std::filesystem::path temp_path_for(const std::filesystem::path& final_path) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  constexpr size_t kMaxNameBytes = 255;  // NAME_MAX of Linux file systems
  std::ostringstream tail;
  tail << ".tmp-" << temp_file_host() << "-" << ::getpid() << "-" << std::hex << rng();
  const std::string name = final_path.filename().string(), rest = tail.str();
  // Bytes left for NAME: the leading '.' and the tail take the others.
  const size_t room = kMaxNameBytes > rest.size() + 2 ? kMaxNameBytes - 1 - rest.size() : name.size();
  std::string kept = ".";
  if (name.size() > room) kept.append("~").append(name, name.size() - (room - 1), std::string::npos);
  else kept.append(name);
  return final_path.parent_path() / (kept + rest);
}

}  // namespace

TempFile::~TempFile() {
  if (fd_ >= 0) ::close(fd_);
  std::error_code ec;
  if (!committed_ && !path_.empty()) std::filesystem::remove(path_, ec);
}

bool TempFile::create(const std::filesystem::path& final_path, std::string& error) {
  // A random name taken by someone else (EEXIST) is drawn again.
  for (int attempt = 0; attempt < 16; ++attempt) {
    const std::filesystem::path candidate = temp_path_for(final_path);
    fd_ = ::open(candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (fd_ >= 0) {
      path_ = candidate;
      return true;
    }
    if (errno != EEXIST) break;
  }
  const std::filesystem::path folder = final_path.has_parent_path() ? final_path.parent_path() : ".";
  error = folder.string() + ": cannot create a temp file: " + std::strerror(errno);
  return false;
}

std::string TempFile::commit(const std::filesystem::path& final_path) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  struct stat st {};
  if (::lstat(final_path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
    return final_path.string() + ": is a folder; the output must be a file name";
  std::error_code ec;
  std::filesystem::rename(path_, final_path, ec);
  if (ec) return final_path.string() + ": cannot rename the temp file into place: " + ec.message();
  committed_ = true;
  return {};
}

std::string write_file_atomically(const std::filesystem::path& path, const std::string& bytes) {
  TempFile temp;
  std::string error;
  if (!temp.create(path, error)) return error;
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(temp.fd(), bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return path.string() + ": cannot write: " + std::strerror(errno);
    done += size_t(n);
  }
  return temp.commit(path);
}

namespace {

namespace fs = std::filesystem;

std::optional<Imf::Compression> parse_compression(const std::string& name) {
  if (name == "none") return Imf::NO_COMPRESSION;
  if (name == "zip") return Imf::ZIP_COMPRESSION;
  if (name == "zips") return Imf::ZIPS_COMPRESSION;
  if (name == "piz") return Imf::PIZ_COMPRESSION;
  if (name == "rle") return Imf::RLE_COMPRESSION;
  if (name == "dwaa") return Imf::DWAA_COMPRESSION;
  return std::nullopt;
}

std::vector<std::string> channel_names(const OutputTerm& t) {
  if (t.image.channels() == 1) return {t.name};
  if (t.vector) return {t.name + ".X", t.name + ".Y", t.name + ".Z"};
  return {t.name + ".R", t.name + ".G", t.name + ".B"};
}

Imath::M44f to_imath(const glm::mat4& m) {
  // Same 16 floats in memory order: glm column-vector form == Imath row-vector form.
  Imath::M44f r;
  std::copy(&m[0][0], &m[0][0] + 16, &r.x[0][0]);
  return r;
}

// sRGB encoding (IEC 61966-2-1) of a linear value clamped to [0, 1].
uint8_t srgb8(float v) {
  if (!std::isfinite(v)) v = 0.0f;
  v = std::clamp(v, 0.0f, 1.0f);
  const float e = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
  return uint8_t(std::lround(e * 255.0f));
}

// srgb8 by the linear values where its byte steps up: step[k] is the smallest float with
// srgb8 >= k (bisection over the bit patterns of [0, 1], ordered as the floats are). The
// floats of [step[1], 1) fall in buckets of at most 2^-10 relative width (their top 10
// mantissa bits), each holding at most one step (the narrowest step, near 1, is 0.9% of
// its value; checked when the table is made): the byte at a bucket's start, plus one past
// its step. srgb8's byte for every float (it is monotonic), without a power per sample.
class SrgbSteps {
 public:
  SrgbSteps() {
    const uint32_t one = std::bit_cast<uint32_t>(1.0f);
    step_[0] = -std::numeric_limits<float>::infinity();
    for (int k = 1; k < 256; ++k) {
      uint32_t lo = 0, hi = one;  // srgb8(0) = 0 < k <= srgb8(1) = 255
      while (hi - lo > 1) {
        const uint32_t mid = lo + (hi - lo) / 2;
        (srgb8(std::bit_cast<float>(mid)) >= k ? hi : lo) = mid;
      }
      step_[size_t(k)] = std::bit_cast<float>(hi);
    }
    step_[256] = std::numeric_limits<float>::infinity();
    first_bucket_ = std::bit_cast<uint32_t>(step_[1]) >> kBucketShift;
    const uint32_t buckets = (one >> kBucketShift) - first_bucket_;
    bucket_byte_.resize(buckets);
    int k = 1;
    for (uint32_t b = 0; b < buckets; ++b) {
      const float start = std::bit_cast<float>((first_bucket_ + b) << kBucketShift);
      const float end = std::bit_cast<float>((first_bucket_ + b + 1) << kBucketShift);
      while (step_[size_t(k + 1)] <= start) ++k;
      bucket_byte_[b] = uint8_t(k);
      if (k < 255 && !(step_[size_t(k + 2)] >= end)) throw std::logic_error("sRGB table: two steps in one bucket");
    }
  }
  uint8_t encode(float v) const {
    if (!(v >= step_[1])) return 0;                     // NaN, negatives, the toe's zeros
    if (!(v < 1.0f)) return std::isfinite(v) ? 255 : 0;  // clamped; +inf is not a number here
    const int k = bucket_byte_[(std::bit_cast<uint32_t>(v) >> kBucketShift) - first_bucket_];
    return uint8_t(k + (v >= step_[size_t(k + 1)] ? 1 : 0));
  }

 private:
  static constexpr int kBucketShift = 13;  // 23 - 10 mantissa bits
  std::array<float, 257> step_;
  uint32_t first_bucket_ = 0;
  std::vector<uint8_t> bucket_byte_;
};

// zlib level 1 (libpng's default is 6): a preview is looked at, not archived; level 1
// deflates a 640x360 term ~4x faster for files ~1.1-1.3x larger.
constexpr int kPreviewZlibLevel = 1;

// Vector terms (unit directions) are shown as 0.5 v + 0.5, linear, the usual normal-map
// colouring: sRGB encoding would bend the mapping of directions to colours.
uint8_t vector8(float v) {
  if (!std::isfinite(v)) v = 0.0f;
  return uint8_t(std::lround(std::clamp(0.5f * v + 0.5f, 0.0f, 1.0f) * 255.0f));
}

std::string write_png(const fs::path& final_path, const OutputTerm& t) {
  const int w = t.image.cols, h = t.image.rows, nc = t.image.channels();
  cv::Mat pixels(h, w, CV_8UC(nc));
  static const SrgbSteps srgb;
  // Half terms a row at a time into floats (exact: every half is a float), not a float copy
  // of the whole term.
  const bool half = t.image.depth() == CV_16F;
  cv::Mat row_floats;
  if (half) row_floats.create(1, w, CV_32FC(nc));  // convertTo writes into it, row after row
  for (int y = 0; y < h; ++y) {
    if (half) t.image.row(y).convertTo(row_floats, CV_32F);
    const float* row = half ? row_floats.ptr<float>(0) : t.image.ptr<float>(y);
    uint8_t* out = pixels.ptr<uint8_t>(y);
    for (int i = 0; i < w * nc; ++i) out[i] = t.vector ? vector8(row[i]) : srgb.encode(row[i]);
  }
  TempFile temp;
  std::string error;
  if (!temp.create(final_path, error)) return error;
  error = write_png_8bit(temp.write_name(), pixels, t.vector ? PngTransfer::linear : PngTransfer::srgb,
                         kPreviewZlibLevel);
  if (!error.empty()) return final_path.string() + ": cannot write PNG preview: " + error;
  return temp.commit(final_path);
}

// The output's data window (the terms' grid at the frame's data origin) and display window.
struct Windows {
  PixelBox data, display;
};

Windows output_windows(const WriteOptions& options, cv::Size size) {
  Windows w;
  w.data = {options.data_x, options.data_y, options.data_x + size.width - 1, options.data_y + size.height - 1};
  w.display = options.display_window.value_or(w.data);
  return w;
}

// The header's camera matrices: the camera is over the data window (the pixel grid);
// worldToNDC is over the display window (projection_for_data_window from the data window
// to the display window: the inverse of the reader's re-targeting).
ExrCameraMatrices header_matrices(const Camera& camera, const Windows& w) {
  if (w.display == w.data) return exr_matrices_from_camera(camera);
  Camera display = camera;
  display.view_to_clip = projection_for_data_window(camera.view_to_clip, w.data, w.display);
  display.width_px = int(w.display.width());
  display.height_px = int(w.display.height());
  return exr_matrices_from_camera(display);
}

// OpenEXR's writer: every compression, and zip, zips and none with ChunkEncoder::openexr.
// Throws on failure (the caller removes the temp file).
void write_exr(const fs::path& temp, const std::vector<OutputTerm>& terms, const Camera& camera,
               const WriteOptions& options, Imf::Compression compression, cv::Size size) {
  const Windows w = output_windows(options, size);
  Imf::Header header(Imath::Box2i({w.display.min_x, w.display.min_y}, {w.display.max_x, w.display.max_y}),
                     Imath::Box2i({w.data.min_x, w.data.min_y}, {w.data.max_x, w.data.max_y}));
  header.compression() = compression;
  header.zipCompressionLevel() = options.zip_level;
  for (const auto& t : terms)
    for (const auto& c : channel_names(t))
      header.channels().insert(c, Imf::Channel(t.type == SampleType::half ? Imf::HALF
                                                                          : Imf::FLOAT));
  const ExrCameraMatrices m = header_matrices(camera, w);
  Imf::addWorldToCamera(header, to_imath(m.world_to_camera));
  Imf::addWorldToNDC(header, to_imath(m.world_to_ndc));
  if (camera.near_view > 0.0f)
    header.insert(kClipNearAttribute, Imf::FloatAttribute(camera.near_view));
  if (camera.far_view > 0.0f)
    header.insert(kClipFarAttribute, Imf::FloatAttribute(camera.far_view));
  for (const auto& [name, value] : options.string_attributes)
    header.insert(name, Imf::StringAttribute(value));

  // OpenEXR writes a slice only into a channel of the same pixel type, so half terms are
  // converted into an interleaved half buffer first; float terms are written in place.
  // A slice is addressed by absolute pixel (x, y): its base is where pixel (0, 0) would be,
  // the grid's first sample moved back by the data window's origin.
  Imf::FrameBuffer fb;
  std::vector<std::vector<half>> half_buffers;
  auto slice = [&](Imf::PixelType type, const void* first, size_t x_stride, size_t y_stride) {
    char* base = const_cast<char*>(static_cast<const char*>(first)) - ptrdiff_t(w.data.min_x) * ptrdiff_t(x_stride) -
                 ptrdiff_t(w.data.min_y) * ptrdiff_t(y_stride);
    return Imf::Slice(type, base, x_stride, y_stride);
  };
  for (const auto& t : terms) {
    const auto channels = channel_names(t);
    const int n = t.image.channels();
    if (t.image.depth() == CV_16F) {  // stored as given
      for (int c = 0; c < n; ++c)
        fb.insert(channels[c], slice(Imf::HALF, t.image.ptr<uint16_t>() + c, sizeof(half) * n, t.image.step[0]));
      continue;
    }
    if (t.type == SampleType::half) {
      std::vector<half>& buffer = half_buffers.emplace_back(size_t(size.area()) * n);
      parallel_rows(cv::Range(0, size.height), options.threads, [&](const cv::Range& rows) {
        for (int y = rows.start; y < rows.end; ++y) {
          // As the own encoders round (saturating beyond half's range).
          half_samples::to_half(t.image.ptr<float>(y), size.width * n,
                                reinterpret_cast<uint16_t*>(buffer.data() + size_t(y) * size.width * n));
        }
      }, 32);
      for (int c = 0; c < n; ++c)
        fb.insert(channels[c], slice(Imf::HALF, buffer.data() + c, sizeof(half) * n, sizeof(half) * n * size.width));
      continue;
    }
    for (int c = 0; c < n; ++c)
      fb.insert(channels[c], slice(Imf::FLOAT, t.image.ptr<float>() + c, sizeof(float) * n, t.image.step[0]));
  }
  {
    // Compression runs on OpenEXR's global pool (sized by its owner, e.g. the worker);
    // asking for N threads makes sure it has N.
    if (options.threads > 1 && Imf::globalThreadCount() < options.threads)
      Imf::setGlobalThreadCount(options.threads);
    const int threads = options.threads > 0 ? options.threads : Imf::globalThreadCount();
    Imf::OutputFile out(temp.c_str(), header, threads);
    out.setFrameBuffer(fb);
    out.writePixels(size.height);
  }  // closed (and flushed) here, before the rename
}

// Throws the failure of an OpenEXRCore call with the library's message.
void check_core(exr_result_t result, const char* action) {
  if (result == EXR_ERR_SUCCESS) return;
  throw std::runtime_error(std::string(action) + ": " + exr_core::error_text(result));
}

// Where one EXR channel's samples come from: component `component` of the pixels of a
// CV_32FC<components> image (converted when the channel is half), or of a CV_16FC<components>
// image (copied).
struct ChannelSource {
  const cv::Mat* image = nullptr;
  int component = 0, components = 1;
  bool is_half = false;
  bool given_half = false;  // the image holds the half samples
};

// A row of `width` pixels of `components` interleaved samples split into one plane per
// channel, the planes one after another in `planes` (kept by the caller while the next
// channels read the same row).
template <class T>
const T* split_row(const T* pixels, int width, int components, UninitializedVector<T>& planes) {
  thread_local std::vector<T*> plane;
  planes.resize(size_t(width) * size_t(components));
  plane.resize(size_t(components));
  for (int k = 0; k < components; ++k) plane[size_t(k)] = planes.data() + size_t(k) * size_t(width);
  sample_planes::split(pixels, width, components, plane.data());
  return planes.data();
}

// Packs scanlines [y0, y1) as a chunk stores them before compression (OpenEXR "Technical
// Introduction", "Scan Line Blocks"; "Pixel Data"): per scanline, for each channel in the
// header's (alphabetical) order, the samples of the whole line, little-endian. Half
// samples are Imath's conversion of the float (round to nearest even), exactly as
// OpenEXR's writer stores them. An image's row is converted to half at once and, with more
// than one channel, split into one plane per channel at once (sample_planes.h), kept while
// the next channels read the same row: each channel's line is then one contiguous copy.
void pack_lines(std::span<const ChannelSource> channels, int width, int y0, int y1,
                uint8_t* out) {
  static_assert(sizeof(half) == 2 && sizeof(float) == 4);
  // Samples are copied in the host's byte order: write_own_exr, the only caller, runs on
  // little-endian hosts only.
  thread_local UninitializedVector<uint16_t> row_half;  // a row converted to half
  // The planes of the row of row_image at row_y, as the image's channels are stored (one
  // image holds one term: one sample type).
  thread_local UninitializedVector<uint16_t> planes_half;
  thread_local UninitializedVector<float> planes_float;
  const cv::Mat* row_image = nullptr;
  int row_y = -1;
  const uint8_t* planes = nullptr;
  for (int y = y0; y < y1; ++y)
    for (const ChannelSource& c : channels) {
      const int components = c.components;
      const size_t line_bytes = size_t(width) * (c.is_half ? 2 : 4);
      const size_t row_samples = size_t(width) * size_t(components);
      // The image's row y as the file stores its samples (interleaved pixels).
      const uint16_t* row_as_half = nullptr;
      if (c.is_half && c.given_half) {
        row_as_half = c.image->ptr<uint16_t>(y);
      } else if (c.is_half && (components == 1 || row_image != c.image || row_y != y)) {
        row_half.resize(row_samples);
        half_samples::to_half(c.image->ptr<float>(y), int(row_samples), row_half.data());
        row_as_half = row_half.data();
      }
      if (components == 1) {
        std::memcpy(out, c.is_half ? static_cast<const void*>(row_as_half) : c.image->ptr<float>(y), line_bytes);
        out += line_bytes;
        continue;
      }
      if (row_image != c.image || row_y != y) {
        planes = c.is_half ? reinterpret_cast<const uint8_t*>(split_row(row_as_half, width, components, planes_half))
                           : reinterpret_cast<const uint8_t*>(
                                 split_row(c.image->ptr<float>(y), width, components, planes_float));
        row_image = c.image;
        row_y = y;
      }
      std::memcpy(out, planes + size_t(c.component) * line_bytes, line_bytes);
      out += line_bytes;
    }
}

// Chunks compressed at a time: at most kBatchPackedBytes of packed data and kBatchChunks
// chunks, but at least 4 per thread so that the strips balance. A batch's compressed
// chunks take at most its packed size (a chunk that does not compress is stored packed).
// Two batches are held (one written while the next is encoded): 8 MiB keeps them small
// beside a frame's terms, and larger batches wrote no faster (1080p, 21 channels).
constexpr size_t kBatchPackedBytes = size_t(8) << 20;
constexpr int kBatchChunks = 256;

// The header of write_own_exr's file, written: the part, its channels and the camera
// attributes. Returns where each channel's samples come from, by channel name.
std::map<std::string, ChannelSource> write_own_header(exr_context_t context, int& part,
                                                      const std::vector<OutputTerm>& terms,
                                                      const Camera& camera,
                                                      const WriteOptions& options,
                                                      Imf::Compression compression, cv::Size size) {
  // Channel names longer than 31 bytes need the long-names flag of the version field
  // (OpenEXR "Technical Introduction", "Version Field"); OpenEXR's writer sets it only then,
  // and so does OpenEXRCore once allowed.
  bool long_names = false;
  for (const auto& t : terms)
    for (const auto& c : channel_names(t)) long_names = long_names || c.size() > 31;
  if (long_names) check_core(exr_set_longname_support(context, 1), "cannot allow long names");
  check_core(exr_add_part(context, nullptr, EXR_STORAGE_SCANLINE, &part), "cannot add the part");
  // The defaults of exr_initialize_required_attr_simple (Imf::Header's too), with the
  // output's windows.
  const Windows w = output_windows(options, size);
  auto box = [](const PixelBox& b) {
    exr_attr_box2i_t out;
    out.min.x = b.min_x, out.min.y = b.min_y, out.max.x = b.max_x, out.max.y = b.max_y;
    return out;
  };
  const exr_attr_box2i_t display = box(w.display), data = box(w.data);
  exr_attr_v2f_t screen_centre;
  screen_centre.x = screen_centre.y = 0.0f;
  check_core(exr_initialize_required_attr(context, part, &display, &data, 1.0f, &screen_centre, 1.0f,
                                          EXR_LINEORDER_INCREASING_Y,
                                          compression == Imf::ZIPS_COMPRESSION  ? EXR_COMPRESSION_ZIPS
                                          : compression == Imf::NO_COMPRESSION ? EXR_COMPRESSION_NONE
                                                                               : EXR_COMPRESSION_ZIP),
             "cannot set the required attributes");
  std::map<std::string, ChannelSource> sources;
  for (const auto& t : terms) {
    const auto names = channel_names(t);
    for (int c = 0; c < int(names.size()); ++c) {
      const bool is_half = t.type == SampleType::half;
      sources[names[size_t(c)]] = {&t.image, c, t.image.channels(), is_half, t.image.depth() == CV_16F};
      // pLinear 0 and sampling 1 x 1: Imf::Channel's defaults, as write_exr adds them.
      check_core(exr_add_channel(context, part, names[size_t(c)].c_str(),
                                 is_half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT,
                                 EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1),
                 "cannot add a channel");
    }
  }
  const ExrCameraMatrices m = header_matrices(camera, w);
  // Same 16 floats in memory order as to_imath's; the names are Imf::addWorldToCamera's and
  // Imf::addWorldToNDC's (ImfStandardAttributes.h).
  exr_attr_m44f_t world_to_camera, world_to_ndc;
  std::copy(&m.world_to_camera[0][0], &m.world_to_camera[0][0] + 16, world_to_camera.m);
  std::copy(&m.world_to_ndc[0][0], &m.world_to_ndc[0][0] + 16, world_to_ndc.m);
  check_core(exr_attr_set_m44f(context, part, "worldToCamera", &world_to_camera),
             "cannot set worldToCamera");
  check_core(exr_attr_set_m44f(context, part, "worldToNDC", &world_to_ndc),
             "cannot set worldToNDC");
  if (camera.near_view > 0.0f)
    check_core(exr_attr_set_float(context, part, kClipNearAttribute, camera.near_view),
               "cannot set clipNear");
  if (camera.far_view > 0.0f)
    check_core(exr_attr_set_float(context, part, kClipFarAttribute, camera.far_view),
               "cannot set clipFar");
  for (const auto& [name, value] : options.string_attributes)
    check_core(exr_attr_set_string(context, part, name.c_str(), value.c_str()),
               "cannot set a string attribute");
  check_core(exr_write_header(context), "cannot write the header");
  return sources;
}

// The chunk layout as the written header defines it: channels in its order, 16 (zip) or
// 1 (zips, none) scanlines per chunk.
struct ChunkLayout {
  std::vector<ChannelSource> order;
  size_t line_bytes = 0;  // one packed line, every channel
  int lines_per_chunk = 0, chunks = 0;
};

ChunkLayout chunk_layout(exr_const_context_t context, int part,
                         const std::map<std::string, ChannelSource>& sources, cv::Size size) {
  const exr_attr_chlist_t* list = nullptr;
  ChunkLayout layout;
  check_core(exr_get_channels(context, part, &list), "cannot read back the channels");
  check_core(exr_get_scanlines_per_chunk(context, part, &layout.lines_per_chunk),
             "cannot read back the chunk height");
  check_core(exr_get_chunk_count(context, part, &layout.chunks), "cannot read back the chunk count");
  for (int c = 0; c < list->num_channels; ++c) {
    const exr_attr_chlist_entry_t& e = list->entries[c];
    const ChannelSource& source = sources.at(std::string(e.name.str, size_t(e.name.length)));
    layout.order.push_back(source);
    layout.line_bytes += size_t(size.width) * (source.is_half ? 2 : 4);
  }
  if (layout.lines_per_chunk < 1 ||
      layout.chunks != (size.height + layout.lines_per_chunk - 1) / layout.lines_per_chunk)
    throw std::runtime_error("unexpected chunk layout");
  return layout;
}

// The stored bytes of the chunk of scanlines [y0, y1): packed, then deflated unless
// `deflate` is off. `packed` is the calling thread's scratch buffer.
void encode_chunk(const ChunkLayout& layout, int width, int y0, int y1, bool deflate,
                  int zip_level, std::vector<uint8_t>& packed, UninitializedVector<uint8_t>& out) {
  if (!deflate) {  // stored as packed
    out.resize(layout.line_bytes * size_t(y1 - y0));
    pack_lines(layout.order, width, y0, y1, out.data());
    return;
  }
  packed.resize(layout.line_bytes * size_t(y1 - y0));
  pack_lines(layout.order, width, y0, y1, packed.data());
  // A chunk deflate does not shrink is stored as packed; readers tell it by its size
  // (OpenEXR "Technical Introduction", "ZIP compression"; ImfZipCompressor.cpp).
  if (!exr_zip::compress(packed, zip_level, out)) out.assign(packed.begin(), packed.end());
}

// Encodes the chunks in batches on the pool and writes them in increasing y order from one
// thread at a time.
void write_own_chunks(exr_context_t context, int part, const ChunkLayout& layout,
                      const WriteOptions& options, bool deflate, cv::Size size) {
  const int chunks = layout.chunks, lines_per_chunk = layout.lines_per_chunk;
  const size_t chunk_bytes = layout.line_bytes * size_t(lines_per_chunk);
  const int threads = options.threads > 0 ? options.threads : std::max(1, cv::getNumThreads());
  const int by_size = int(std::clamp<size_t>(kBatchPackedBytes / chunk_bytes, 1, kBatchChunks));
  const int batch = std::min(chunks, std::max(4 * threads, by_size));
  // Two sets of chunk buffers: while one batch is written to the file (a thread of its own:
  // the copy into the page cache is serial), the next is packed and compressed into the
  // other on the pool.
  // Not zeroed when they grow: every byte is written before it is read.
  std::vector<UninitializedVector<uint8_t>> stored[2];
  stored[0].resize(size_t(batch));
  stored[1].resize(size_t(batch));
  std::thread writing;
  std::exception_ptr write_error;
  const auto finish_writing = [&] {
    if (writing.joinable()) writing.join();
    if (write_error) std::rethrow_exception(write_error);
  };
  const auto write_batch = [&](int first, int count, int b) {
    try {
      exr_core::forget_error();
      for (int i = 0; i < count; ++i) {
        const UninitializedVector<uint8_t>& bytes = stored[b][size_t(i)];
        check_core(exr_write_scanline_chunk(context, part, options.data_y + (first + i) * lines_per_chunk,
                                            bytes.data(), bytes.size()),
                   "cannot write a chunk");
      }
    } catch (...) {
      write_error = std::current_exception();
    }
  };
  try {
    for (int first = 0, b = 0; first < chunks; first += batch, b ^= 1) {
      const int count = std::min(batch, chunks - first);
      std::vector<UninitializedVector<uint8_t>>& out = stored[b];
      parallel_rows(cv::Range(0, count), options.threads, [&](const cv::Range& range) {
        // One packed chunk per thread, kept like exr_zip's own scratch buffer.
        thread_local std::vector<uint8_t> packed;
        for (int i = range.start; i < range.end; ++i) {
          const int y0 = (first + i) * lines_per_chunk;
          const int y1 = std::min(y0 + lines_per_chunk, size.height);
          encode_chunk(layout, size.width, y0, y1, deflate, options.zip_level, packed, out[size_t(i)]);
        }
      }, 1);
      finish_writing();  // the previous batch, whose buffers the next one reuses
      writing = std::thread(write_batch, first, count, b);
    }
    finish_writing();
  } catch (...) {
    if (writing.joinable()) writing.join();
    throw;
  }
}

// zip, zips and none with ChunkEncoder::own: the header and the chunk table are
// OpenEXRCore's; the chunks are packed (and deflated, formats/exr_zip) here in parallel, in
// batches, and written in increasing y order from one thread at a time, as OpenEXR's
// writer orders them (lineOrder INCREASING_Y). The header carries the same attributes as
// write_exr's, plus the "type" attribute ("scanlineimage") OpenEXRCore 3.1 writes into
// every part (optional in single-part files, which readers accept); the zip level is not
// among them (OpenEXR keeps it out of the file). Little-endian hosts only (the packed
// samples are the in-memory bytes). Throws on failure (the caller removes the temp file).
void write_own_exr(const fs::path& temp, const std::vector<OutputTerm>& terms,
                   const Camera& camera, const WriteOptions& options, Imf::Compression compression,
                   cv::Size size) {
  exr_core::forget_error();
  // Closed on failure (the caller removes the file), finished explicitly on success.
  exr_core::Context file;
  const exr_context_initializer_t init = exr_core::quiet_initializer();
  check_core(exr_start_write(file.out(), temp.c_str(), EXR_WRITE_FILE_DIRECTLY, &init),
             "cannot create the file");
  int part = 0;
  const std::map<std::string, ChannelSource> sources =
      write_own_header(file.get(), part, terms, camera, options, compression, size);
  const ChunkLayout layout = chunk_layout(file.get(), part, sources, size);
  write_own_chunks(file.get(), part, layout, options, compression != Imf::NO_COMPRESSION, size);
  // Writes the chunk offset table and closes the file.
  check_core(file.finish(), "cannot finish the file");
}

std::string write_outputs_unguarded(const std::string& path, const std::vector<OutputTerm>& terms,
                                    const Camera& camera, const WriteOptions& options,
                                    ResourceFailure& exhausted) {
  const fs::path final_path(path);
  if (terms.empty()) return path + ": no output terms to write";
  const auto compression = parse_compression(options.compression);
  if (!compression)
    return path + ": unknown compression \"" + options.compression +
           "\" (use zip, zips, piz, rle, none, or dwaa for colour terms)";
  if (options.zip_level < 1 || options.zip_level > 9)
    return path + ": zip level " + std::to_string(options.zip_level) + " is not in [1, 9]";
  std::set<std::string> names;
  const cv::Size size = terms[0].image.size();
  for (const auto& t : terms) {
    if (t.name.empty()) return path + ": an output term has no name";
    if (!names.insert(t.name).second) return path + ": output term \"" + t.name + "\" given twice";
    if (t.image.empty()) return path + ": output term \"" + t.name + "\" has no image";
    const bool given_half = t.image.type() == CV_16FC1 || t.image.type() == CV_16FC3;
    if (t.image.type() != CV_32FC1 && t.image.type() != CV_32FC3 && !(given_half && t.type == SampleType::half))
      return path + ": output term \"" + t.name + "\" must be CV_32FC1 or CV_32FC3" +
             (given_half ? " (CV_16F only for half terms)" : "");
    if (t.image.size() != size)
      return path + ": output term \"" + t.name + "\" is " + std::to_string(t.image.cols) + "x" +
             std::to_string(t.image.rows) + ", the others " + std::to_string(size.width) + "x" +
             std::to_string(size.height);
    // DWAA quantises in a perceptual colour space: fine for pictures, wrong for numbers
    // (AO, confidences) and directions that later stages compute with.
    if (*compression == Imf::DWAA_COMPRESSION && (t.image.channels() == 1 || t.vector))
      return path + ": dwaa compression is lossy and only allowed for colour terms; \"" +
             t.name + "\" is a " + (t.vector ? "vector" : "numeric") + " term (use zip or piz)";
  }
  if (camera.width_px > 0 && (camera.width_px != size.width || camera.height_px != size.height))
    return path + ": terms are " + std::to_string(size.width) + "x" +
           std::to_string(size.height) + " but the camera grid is " +
           std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px);
  std::error_code ec;
  const fs::path folder = final_path.has_parent_path() ? final_path.parent_path() : fs::path(".");
  if (!fs::is_directory(folder, ec)) return path + ": output folder does not exist";

  if (fs::is_directory(final_path, ec)) return path + ": is a folder; the output must be a file name";
  // Every name before any byte: a preview whose name the file system refuses would fail the
  // frame after the previews before it were written.
  constexpr size_t kMaxNameBytes = 255;  // NAME_MAX of Linux file systems
  for (const OutputTerm& t : terms)
    if (const std::string name = fs::path(preview_path(path, t.name)).filename().string();
        options.png_previews && name.size() > kMaxNameBytes)
      return path + ": the preview name " + name + " is " + std::to_string(name.size()) +
             " bytes, over a file name's 255: shorten the frame's name, or leave out --png";
  TempFile temp;
  if (std::string error; !temp.create(final_path, error)) return error;
  try {
    const bool own = *compression == Imf::ZIP_COMPRESSION || *compression == Imf::ZIPS_COMPRESSION ||
                     *compression == Imf::NO_COMPRESSION;
    if (own && options.chunk_encoder == ChunkEncoder::own && std::endian::native == std::endian::little)
      write_own_exr(temp.write_name(), terms, camera, options, *compression, size);
    else
      write_exr(temp.write_name(), terms, camera, options, *compression, size);
  } catch (const std::exception& e) {
    exhausted = resource_failure(e);
    return path + ": cannot write EXR: " + e.what();
  }
  if (options.png_previews) {
    // One preview per term, written side by side on the write's threads, before the EXR is
    // renamed into place: an output's EXR then means its previews exist too, so a rerun
    // that skips up-to-date EXRs never leaves previews missing (the EXR is the frame's
    // completion mark). The first term's error in the terms' order is the one reported;
    // the EXR's temp file is then removed.
    std::vector<std::string> errors(terms.size());
    parallel_rows(cv::Range(0, int(terms.size())), options.threads, [&](const cv::Range& r) {
      for (int i = r.start; i < r.end; ++i) {
        const OutputTerm& t = terms[size_t(i)];
        errors[size_t(i)] = write_png(fs::path(preview_path(path, t.name)), t);
      }
    }, 1);
    for (const std::string& error : errors)
      if (!error.empty()) return error;
  }
  return temp.commit(final_path);
}

}  // namespace

std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options, ResourceFailure& exhausted) {
  // Nothing throws across the API: file-system, OpenCV or allocation failures outside the
  // EXR writing itself end up here as messages too.
  exhausted = ResourceFailure::none;
  try {
    return write_outputs_unguarded(path, terms, camera, options, exhausted);
  } catch (const std::exception& e) {
    exhausted = resource_failure(e);
    return path + ": cannot write outputs: " + e.what();
  } catch (...) {
    return path + ": cannot write outputs: unknown error";
  }
}

std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options) {
  ResourceFailure exhausted;
  return write_outputs(path, terms, camera, options, exhausted);
}

std::string preview_path(const std::string& output, const std::string& term) {
  const fs::path out(output);
  const std::string stem = out.stem().string(), suffix = "." + term;
  const bool named_after = stem.size() > suffix.size() && stem.ends_with(suffix);
  return (out.parent_path() / (stem + (named_after ? "" : suffix) + ".png")).string();
}

namespace {

// OpenEXRCore's reads of a file already open (pread: the descriptor's offset is not used), so
// the context does not open it again by name.
int64_t read_open_file(exr_const_context_t context, void* fd, void* buffer, uint64_t size, uint64_t offset,
                       exr_stream_error_func_ptr_t error_cb) {
  auto* out = static_cast<char*>(buffer);
  uint64_t got = 0;
  while (got < size) {
    const ssize_t n = ::pread(*static_cast<const int*>(fd), out + got, size_t(size - got), off_t(offset + got));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      if (error_cb) error_cb(context, EXR_ERR_READ_IO, "cannot read: %s", std::strerror(errno));
      return -1;
    }
    if (n == 0) break;  // the end of the file: OpenEXRCore reports the short read
    got += uint64_t(n);
  }
  return int64_t(got);
}

int64_t size_of_open_file(exr_const_context_t, void* fd) {
  struct stat st {};
  return ::fstat(*static_cast<const int*>(fd), &st) == 0 ? int64_t(st.st_size) : -1;
}

// An EXR opened once for reading its headers: the descriptor, its size, and an OpenEXRCore
// context reading through it, after its headers passed check_exr_headers.
class OpenedExr {
 public:
  explicit OpenedExr(const std::string& path) : fd_(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
    if (fd_ < 0) return;
    const ExrHeaderCheck check = check_exr_headers(fd_, path);
    if (!check.ok()) return;
    bytes_ = check.file_bytes;
    exr_context_initializer_t init = exr_core::quiet_initializer();
    init.flags = EXR_CONTEXT_FLAG_SILENT_HEADER_PARSE;
    init.user_data = &fd_;
    init.read_fn = &read_open_file;
    init.size_fn = &size_of_open_file;
    if (exr_start_read(file_.out(), path.c_str(), &init) != EXR_ERR_SUCCESS) file_.finish();
  }
  OpenedExr(const OpenedExr&) = delete;
  OpenedExr& operator=(const OpenedExr&) = delete;
  ~OpenedExr() {
    file_.finish();  // before the descriptor it reads through
    if (fd_ >= 0) ::close(fd_);
  }
  // Null when the file cannot be opened or read, or its headers are refused.
  exr_const_context_t context() const { return file_.get(); }
  int64_t bytes() const { return bytes_; }

 private:
  int fd_;
  int64_t bytes_ = 0;
  exr_core::Context file_;
};

std::vector<std::optional<std::string>> string_attributes(const OpenedExr& file,
                                                          const std::vector<std::string>& names) {
  std::vector<std::optional<std::string>> values(names.size());
  if (!file.context()) return values;
  for (size_t i = 0; i < names.size(); ++i) {
    int32_t length = 0;
    const char* value = nullptr;
    if (exr_attr_get_string(file.context(), 0, names[i].c_str(), &length, &value) == EXR_ERR_SUCCESS &&
        value != nullptr && length >= 0)
      values[i] = std::string(value, size_t(length));
  }
  return values;
}

bool scanline_chunks_complete(const OpenedExr& file) {
  if (!file.context()) return false;
  int parts = 0;
  if (exr_get_count(file.context(), &parts) != EXR_ERR_SUCCESS) return false;
  for (int part = 0; part < parts; ++part) {
    exr_storage_t storage{};
    exr_attr_box2i_t window{};
    int32_t lines = 0;
    if (exr_get_storage(file.context(), part, &storage) != EXR_ERR_SUCCESS) return false;
    if (storage != EXR_STORAGE_SCANLINE) continue;  // not what write_outputs writes
    if (exr_get_data_window(file.context(), part, &window) != EXR_ERR_SUCCESS ||
        exr_get_scanlines_per_chunk(file.context(), part, &lines) != EXR_ERR_SUCCESS || lines <= 0)
      return false;
    // Every chunk's offset (the table) and its block within the file: a file cut short, or
    // whose blocks were never written (zeros after a crash), has offsets that are not.
    for (int64_t y = window.min.y; y <= window.max.y; y += lines) {
      exr_chunk_info_t chunk{};
      if (exr_read_scanline_chunk_info(file.context(), part, int(y), &chunk) != EXR_ERR_SUCCESS ||
          chunk.data_offset + chunk.packed_size > uint64_t(file.bytes()))
        return false;
    }
  }
  return true;
}

}  // namespace

std::vector<std::optional<std::string>> read_string_attributes(const std::string& path,
                                                               const std::vector<std::string>& names) {
  return string_attributes(OpenedExr(path), names);
}

std::optional<std::string> read_string_attribute(const std::string& path, const std::string& name) {
  return read_string_attributes(path, {name})[0];
}

ExistingOutput read_existing_output(const std::string& path, const std::vector<std::string>& names) {
  const OpenedExr file(path);
  ExistingOutput out{string_attributes(file, names), scanline_chunks_complete(file), {}};
  const exr_attr_chlist_t* list = nullptr;
  if (file.context() && exr_get_channels(file.context(), 0, &list) == EXR_ERR_SUCCESS && list)
    for (int c = 0; c < list->num_channels; ++c)
      out.channels.emplace_back(list->entries[c].name.str, size_t(list->entries[c].name.length));
  return out;
}

}  // namespace ssdo
