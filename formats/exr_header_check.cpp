#include "formats/exr_header_check.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <optional>

#include <OpenEXR/OpenEXRConfig.h>

namespace ssdo {

namespace {

constexpr uint32_t kMagic = 20000630;  // 76 2f 31 01
constexpr int kVersion = 2;
constexpr uint32_t kTiledFlag = 0x200, kLongNamesFlag = 0x400, kNonImageFlag = 0x800,
                   kMultiPartFlag = 0x1000;
// OpenEXR reads names (attribute, type, channel) as at most 255 characters up to a zero
// byte; a 255-character name leaves its terminator unread.
constexpr int kMaxNameLength = 255;
// Counts beyond this are refused anyway (no file is that large); products saturate here.
constexpr int64_t kCap = int64_t(1) << 62;

// A name from the file, fit for a message: at most 64 characters, bytes outside printable
// ASCII as \xNN.
std::string printable(const std::string& name) {
  std::string out;
  for (size_t i = 0; i < name.size() && i < 64; ++i) {
    const unsigned char c = static_cast<unsigned char>(name[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out.push_back(char(c));
    } else {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", c);
      out += b;
    }
  }
  if (name.size() > 64) out += "...";
  return out;
}

int64_t sat_add(int64_t a, int64_t b) { return std::min(kCap, a + b); }
int64_t sat_mul(int64_t a, int64_t b) {
  if (a == 0 || b == 0) return 0;
  return a > kCap / b ? kCap : a * b;
}

// Little-endian reads through a 64 KiB window of the file.
class Source {
 public:
  Source(int fd, int64_t size) : fd_(fd), size_(size) {}
  int64_t size() const { return size_; }
  bool read(int64_t pos, void* out, int64_t n) {
    if (pos < 0 || n < 0 || pos > size_ || n > size_ - pos) return false;
    auto* dst = static_cast<unsigned char*>(out);
    while (n > 0) {
      if (pos < start_ || pos >= start_ + int64_t(len_)) {
        if (!fill(pos)) return false;
      }
      const int64_t take = std::min<int64_t>(n, start_ + int64_t(len_) - pos);
      std::memcpy(dst, buf_ + (pos - start_), size_t(take));
      dst += take;
      pos += take;
      n -= take;
    }
    return true;
  }
  bool i32(int64_t pos, int32_t& v) {
    unsigned char b[4];
    if (!read(pos, b, 4)) return false;
    v = int32_t(uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 | uint32_t(b[3]) << 24);
    return true;
  }
  bool u8(int64_t pos, uint8_t& v) { return read(pos, &v, 1); }

 private:
  bool fill(int64_t pos) {
    const size_t want = size_t(std::min<int64_t>(sizeof(buf_), size_ - pos));
    size_t got = 0;
    while (got < want) {
      const ssize_t n = ::pread(fd_, buf_ + got, want - got, off_t(pos + int64_t(got)));
      if (n <= 0) return false;
      got += size_t(n);
    }
    start_ = pos;
    len_ = got;
    return true;
  }
  int fd_;
  int64_t size_;
  int64_t start_ = 0;
  size_t len_ = 0;
  unsigned char buf_[65536];
};

// Bytes OpenEXR's reader consumes for a fixed-size attribute type, whatever size the file
// declares.
std::optional<int> fixed_size(const std::string& type) {
  static const std::map<std::string, int> sizes = {
      {"box2i", 16}, {"box2f", 16},    {"chromaticities", 32}, {"compression", 1},
      {"deepImageState", 1}, {"double", 8}, {"envmap", 1},     {"float", 4},
      {"int", 4},    {"keycode", 28},  {"lineOrder", 1},       {"m33d", 72},
      {"m33f", 36},  {"m44d", 128},    {"m44f", 64},           {"rational", 8},
      {"tiledesc", 9}, {"timecode", 8}, {"v2d", 16},           {"v2f", 8},
      {"v2i", 8},    {"v3d", 24},      {"v3f", 12},            {"v3i", 12}};
  if (auto it = sizes.find(type); it != sizes.end()) return it->second;
  return std::nullopt;
}

// Types OpenEXR's Header always holds (from its default constructor): a file attribute of
// that name but another type is refused by OpenEXR too.
const char* predefined_type(const std::string& name) {
  static const std::map<std::string, const char*> types = {
      {"displayWindow", "box2i"}, {"dataWindow", "box2i"},       {"pixelAspectRatio", "float"},
      {"screenWindowCenter", "v2f"}, {"screenWindowWidth", "float"}, {"lineOrder", "lineOrder"},
      {"compression", "compression"}, {"channels", "chlist"}};
  auto it = types.find(name);
  return it == types.end() ? nullptr : it->second;
}

int lines_per_chunk(int compression) {
  switch (compression) {
    case 0: case 1: case 2: return 1;    // NONE, RLE, ZIPS
    case 3: case 5: return 16;           // ZIP, PXR24
    case 4: case 6: case 7: case 8: return 32;  // PIZ, B44, B44A, DWAA
    case 9: return 256;                  // DWAB
    default: return 0;
  }
}

int64_t floor_div(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// OpenEXR's numSamples: how many multiples of s lie in [a, b].
int64_t num_samples(int64_t s, int64_t a, int64_t b) {
  const int64_t a1 = floor_div(a, s), b1 = floor_div(b, s);
  return b1 - a1 + ((a1 * s < a) ? 0 : 1);
}

int round_log2(int64_t x, int rounding) {
  int y = 0, r = 0;
  while (x > 1) {
    if (x & 1) r = 1;
    ++y;
    x >>= 1;
  }
  return rounding == 1 ? y + r : y;
}

int64_t level_size(int64_t extent, int level, int rounding) {
  const int64_t b = int64_t(1) << level;
  int64_t size = extent / b;
  if (rounding == 1 && size * b < extent) size += 1;
  return std::max<int64_t>(size, 1);
}

// Entries of a tiled part's offset table: tiles over every level, as OpenEXR counts them.
int64_t tiled_chunks(int64_t w, int64_t h, int64_t tx, int64_t ty, int mode, int rounding) {
  auto tiles = [](int64_t extent, int64_t tile) { return (extent + tile - 1) / tile; };
  if (mode == 0) return sat_mul(tiles(w, tx), tiles(h, ty));
  if (mode == 1) {
    const int levels = round_log2(std::max(w, h), rounding) + 1;
    int64_t n = 0;
    for (int l = 0; l < levels; ++l)
      n = sat_add(n, sat_mul(tiles(level_size(w, l, rounding), tx),
                             tiles(level_size(h, l, rounding), ty)));
    return n;
  }
  int64_t nx = 0, ny = 0;
  for (int l = 0; l <= round_log2(w, rounding); ++l)
    nx = sat_add(nx, tiles(level_size(w, l, rounding), tx));
  for (int l = 0; l <= round_log2(h, rounding); ++l)
    ny = sat_add(ny, tiles(level_size(h, l, rounding), ty));
  return sat_mul(nx, ny);
}

struct ChannelInfo {
  int type = 0;
  int64_t x_sampling = 1, y_sampling = 1;
};

struct PartWalk {
  ExrPartLayout layout;
  std::optional<std::string> type_attribute;
  std::optional<int64_t> chunk_count;
  bool has_tiles = false;
  int level_mode = 0, rounding = 0;
  std::map<std::string, ChannelInfo> channels;
};

class Walker {
 public:
  Walker(Source& src, std::string path, const ExrLimits& limits)
      : src_(src), path_(std::move(path)), limits_(limits) {}

  bool run(ExrHeaderCheck& out) {
    int32_t magic = 0, version = 0;
    if (!src_.i32(0, magic) || uint32_t(magic) != kMagic) {
      error_ = path_ + ": not an OpenEXR file (no EXR magic number)";
      return fail(out);
    }
    if (!src_.i32(4, version)) return fail(out, "truncated: the file ends inside the version field");
    const uint32_t v = uint32_t(version);
    if ((v & 0xff) != kVersion)
      return fail(out, "file format version " + std::to_string(v & 0xff) + " (OpenEXR files are version 2)");
    const uint32_t flags = v & ~0xffu;
    if (flags & ~(kTiledFlag | kLongNamesFlag | kNonImageFlag | kMultiPartFlag))
      return fail(out, "unknown flags in the version field (" + hex(flags) + ")");
    multipart_ = flags & kMultiPartFlag;
    tiled_flag_ = flags & kTiledFlag;
    non_image_ = flags & kNonImageFlag;
    if (multipart_ && tiled_flag_) return fail(out, "version field sets both the tiled and the multi-part flag");

    int64_t pos = 8;
    while (true) {
      PartWalk part;
      bool empty = true;
      if (!read_header(pos, part, empty)) return fail(out);
      if (empty) break;
      parts_.push_back(std::move(part));
      if (!multipart_) break;
    }
    if (parts_.empty()) return fail(out, "no header");
    out.header_bytes = pos;

    // Types, pixel sizes and offset tables.
    int64_t need = pos;
    for (size_t i = 0; i < parts_.size(); ++i) {
      if (!finish_part(i, parts_[i]) || !check_limits(i, parts_[i].layout)) return fail(out);
      need = sat_add(need, sat_mul(parts_[i].layout.chunks, 8));
      if (need > src_.size())
        return fail(out, label(i) + std::to_string(parts_[i].layout.chunks) +
                             " chunks: their offset table (8 bytes each) ends at byte " +
                             std::to_string(need) + ", past the end of the file (" +
                             std::to_string(src_.size()) + " bytes; truncated or damaged)");
    }
    // Uncompressed image parts store every sample as is: the file must hold them.
    for (size_t i = 0; i < parts_.size(); ++i) {
      const ExrPartLayout& p = parts_[i].layout;
      if (p.compression != 0 || (p.type != "scanlineimage" && p.type != "tiledimage")) continue;
      int64_t bytes = 0;
      for (const auto& [name, c] : parts_[i].channels) {
        const int64_t samples = sat_mul(num_samples(c.x_sampling, p.min_x, p.max_x),
                                        num_samples(c.y_sampling, p.min_y, p.max_y));
        bytes = sat_add(bytes, sat_mul(samples, c.type == 1 ? 2 : 4));
      }
      need = sat_add(need, bytes);
      if (need > src_.size())
        return fail(out, label(i) + "uncompressed pixels of data window " +
                             std::to_string(p.max_x - p.min_x + 1) + "x" +
                             std::to_string(p.max_y - p.min_y + 1) + " (" +
                             std::to_string(p.bytes_per_pixel) + " bytes per pixel) need " +
                             std::to_string(bytes) + " bytes; the file has " +
                             std::to_string(src_.size()) + " bytes in all (truncated or damaged)");
    }
    for (auto& p : parts_) out.parts.push_back(p.layout);
    return true;
  }

 private:
  bool fail(ExrHeaderCheck& out, const std::string& what = {}) {
    if (!what.empty()) error_ = path_ + ": " + what;
    out.error = error_;
    return false;
  }
  bool set_error(const std::string& what) {
    error_ = path_ + ": " + what;
    return false;
  }
  static std::string hex(uint32_t v) {
    char b[16];
    std::snprintf(b, sizeof b, "0x%x", v);
    return b;
  }
  std::string label(size_t part) const {
    return multipart_ ? "part " + std::to_string(part) + ": " : std::string();
  }
  std::string where() const { return label(parts_.size()); }

  // A zero-terminated name as OpenEXR reads it.
  bool read_name(int64_t& pos, std::string& name, const std::string& what) {
    name.clear();
    for (int i = 0; i < kMaxNameLength; ++i) {
      uint8_t c = 0;
      if (!src_.u8(pos + i, c)) return set_error(where() + "truncated: the file ends inside " + what);
      if (c == 0) {
        pos += i + 1;
        return true;
      }
      name.push_back(char(c));
    }
    return set_error(where() + what + " \"" + printable(name) +
                     "\" has no terminator within " + std::to_string(kMaxNameLength - 1) +
                     " characters");
  }

  bool read_header(int64_t& pos, PartWalk& part, bool& empty) {
    empty = true;
    while (true) {
      std::string name, type;
      if (!read_name(pos, name, "an attribute name")) return false;
      if (name.empty()) return true;
      empty = false;
      if (!read_name(pos, type, "the type of attribute \"" + printable(name) + "\"")) return false;
      int32_t size = 0;
      if (!src_.i32(pos, size))
        return set_error(where() + "truncated: the file ends inside the size of attribute \"" + printable(name) + "\"");
      pos += 4;
      const std::string attr = "attribute \"" + printable(name) + "\" (" + printable(type) + ")";
      if (size < 0) return set_error(where() + attr + " declares a negative size (" + std::to_string(size) + ")");
      const int64_t remaining = src_.size() - pos;
      if (size > remaining)
        return set_error(where() + attr + " declares " + std::to_string(size) +
                         " bytes, but only " + std::to_string(remaining) +
                         " bytes of the file follow (damaged or truncated header)");
      if (const char* expected = predefined_type(name); expected && type != expected)
        return set_error(where() + attr + ": \"" + name + "\" must be of type " + expected);
      if (auto fixed = fixed_size(type)) {
        if (size != *fixed)
          return set_error(where() + attr + " declares " + std::to_string(size) +
                           " bytes; a " + type + " value is " + std::to_string(*fixed));
      } else if (type == "chlist") {
        if (!read_channels(pos, size, attr, part)) return false;
      } else if (type == "stringvector") {
        int64_t r = 0;
        while (r < size) {
          int32_t n = 0;
          if (size - r < 4 || !src_.i32(pos + r, n) || n < 0 || n > size - r - 4)
            return set_error(where() + attr + ": an entry runs past the attribute's " +
                             std::to_string(size) + " bytes");
          r += 4 + n;
        }
      } else if (type == "floatvector") {
        if (size % 4 != 0)
          return set_error(where() + attr + " declares " + std::to_string(size) +
                           " bytes, not a whole number of floats");
      } else if (type == "preview") {
        int32_t w = 0, h = 0;
        if (size < 8 || !src_.i32(pos, w) || !src_.i32(pos + 4, h) ||
            sat_add(8, sat_mul(sat_mul(uint32_t(w), uint32_t(h)), 4)) != size)
          return set_error(where() + attr + ": a " + std::to_string(uint32_t(w)) + "x" +
                           std::to_string(uint32_t(h)) + " preview does not match its " +
                           std::to_string(size) + " bytes");
      } else if (type == "idmanifest") {
#if OPENEXR_VERSION_MAJOR == 3 && OPENEXR_VERSION_MINOR < 2
        // OpenEXR 3.1 writes 8 + N bytes and declares them, then reads 8 + (size - 4):
        // four bytes past the attribute, and the rest of the header out of step.
        return set_error(where() + attr + ": ID manifests cannot be read by OpenEXR " +
                         OPENEXR_VERSION_STRING + " (it reads past the declared size)");
#else
        if (size < 8) return set_error(where() + attr + " is shorter than 8 bytes");
#endif
      }
      if (!interpret(pos, name, type, size, part)) return false;
      pos += size;
    }
  }

  bool read_channels(int64_t pos, int32_t size, const std::string& attr, PartWalk& part) {
    const int64_t end = pos + size;
    part.channels.clear();
    while (true) {
      std::string name;
      if (pos >= end || !read_name(pos, name, "a channel name of " + attr)) {
        if (error_.empty())
          set_error(where() + attr + ": the channel list runs past the attribute's " +
                    std::to_string(size) + " bytes");
        return false;
      }
      if (name.empty()) break;
      int32_t type = 0, xs = 0, ys = 0;
      if (end - pos < 16 || !src_.i32(pos, type) || !src_.i32(pos + 8, xs) || !src_.i32(pos + 12, ys))
        return set_error(where() + attr + ": channel \"" + printable(name) +
                         "\" runs past the attribute's " + std::to_string(size) + " bytes");
      pos += 16;
      if (type < 0 || type > 2)
        return set_error(where() + attr + ": channel \"" + printable(name) + "\" has pixel type " +
                         std::to_string(type) + " (0 uint, 1 half, 2 float)");
      if (xs < 1 || ys < 1)
        return set_error(where() + attr + ": channel \"" + printable(name) + "\" has sampling " +
                         std::to_string(xs) + "x" + std::to_string(ys));
      part.channels[name] = {type, xs, ys};
    }
    if (pos != end)
      return set_error(where() + attr + ": the channel list ends after " +
                       std::to_string(size - (end - pos)) + " of its declared " +
                       std::to_string(size) + " bytes");
    return true;
  }

  // The attributes buffers are sized from.
  bool interpret(int64_t pos, const std::string& name, const std::string& type, int32_t size,
                 PartWalk& part) {
    ExrPartLayout& p = part.layout;
    if (name == "dataWindow" && type == "box2i") {
      int32_t v[4];
      for (int i = 0; i < 4; ++i) src_.i32(pos + 4 * i, v[i]);
      // OpenEXR's own bounds (Header::sanityCheck), so that its int arithmetic holds.
      const int64_t lim = INT_MAX / 2;
      if (v[0] > v[2] || v[1] > v[3] || v[0] <= -lim || v[1] <= -lim || v[2] >= lim || v[3] >= lim)
        return set_error(where() + "data window (" + std::to_string(v[0]) + ", " +
                         std::to_string(v[1]) + ") - (" + std::to_string(v[2]) + ", " +
                         std::to_string(v[3]) + ") is empty or out of range");
      p.min_x = v[0], p.min_y = v[1], p.max_x = v[2], p.max_y = v[3];
    } else if (name == "compression" && type == "compression") {
      uint8_t c = 0;
      src_.u8(pos, c);
      if (lines_per_chunk(c) == 0)
        return set_error(where() + "unknown compression " + std::to_string(c));
      p.compression = c;
    } else if (name == "tiles" && type == "tiledesc") {
      int32_t tx = 0, ty = 0;
      uint8_t mode = 0;
      src_.i32(pos, tx);
      src_.i32(pos + 4, ty);
      src_.u8(pos + 8, mode);
      part.level_mode = mode & 0x0f;
      part.rounding = mode >> 4;
      if (uint32_t(tx) == 0 || uint32_t(ty) == 0 || uint32_t(tx) > INT_MAX ||
          uint32_t(ty) > INT_MAX || part.level_mode > 2 || part.rounding > 1)
        return set_error(where() + "tile description " + std::to_string(uint32_t(tx)) + "x" +
                         std::to_string(uint32_t(ty)) + " mode " + std::to_string(mode) +
                         " is invalid");
      p.tile_x = tx, p.tile_y = ty;
      part.has_tiles = true;
    } else if (name == "type" && type == "string") {
      std::string t(size_t(size), '\0');
      src_.read(pos, t.data(), size);
      part.type_attribute = t;
    } else if (name == "chunkCount" && type == "int") {
      int32_t n = 0;
      src_.i32(pos, n);
      if (n < 0) return set_error(where() + "chunkCount " + std::to_string(n) + " is negative");
      part.chunk_count = n;
    }
    return true;
  }

  bool finish_part(size_t i, PartWalk& part) {
    ExrPartLayout& p = part.layout;
    if (!multipart_ && !non_image_)
      p.type = tiled_flag_ ? "tiledimage" : "scanlineimage";  // OpenEXR ignores the attribute
    else if (part.type_attribute)
      p.type = *part.type_attribute;
    else if (multipart_)
      return set_error(label(i) + "no type attribute (every part of a multi-part file needs one)");
    else
      p.type = tiled_flag_ ? "tiledimage" : "scanlineimage";
    p.tiled = p.type == "tiledimage" || p.type == "deeptile";
    p.channels = int(part.channels.size());
    for (const auto& [name, c] : part.channels)
      p.bytes_per_pixel += c.type == 1 ? 2 : 4;
    const int64_t w = p.max_x - p.min_x + 1, h = p.max_y - p.min_y + 1;
    std::optional<int64_t> computed;
    if (p.tiled) {
      if (!part.has_tiles) return set_error(label(i) + "a tiled part without a tile description (\"tiles\")");
      computed = tiled_chunks(w, h, p.tile_x, p.tile_y, part.level_mode, part.rounding);
    } else if (p.type == "scanlineimage" || p.type == "deepscanline") {
      const int lines = lines_per_chunk(p.compression);
      computed = (h + lines - 1) / lines;
    }
    if (part.chunk_count && computed && *part.chunk_count != *computed)
      return set_error(label(i) + "chunkCount " + std::to_string(*part.chunk_count) +
                       ", but the data window, compression and tiling give " +
                       std::to_string(*computed) + " chunks");
    if (!computed && !part.chunk_count)
      return set_error(label(i) + "part type \"" + printable(p.type) + "\" is unknown and has no chunkCount");
    p.chunks = computed ? *computed : *part.chunk_count;
    return true;
  }

  // The blocks OpenEXR allocates for a part, against the limits.
  bool check_limits(size_t i, const ExrPartLayout& p) {
    const int64_t w = p.max_x - p.min_x + 1, h = p.max_y - p.min_y + 1;
    const std::string window = std::to_string(w) + "x" + std::to_string(h) + " at (" +
                               std::to_string(p.min_x) + ", " + std::to_string(p.min_y) + ")";
    struct Block {
      std::string what;
      int64_t pixels;
    };
    std::vector<Block> blocks{{"data window " + window, sat_mul(w, h)}};
    if (p.tiled) {
      blocks.push_back({"tiles of " + std::to_string(p.tile_x) + "x" + std::to_string(p.tile_y),
                        sat_mul(p.tile_x, p.tile_y)});
      blocks.push_back({"a row of " + std::to_string(p.tile_y) + "-line tiles across the " +
                            std::to_string(w) + "-pixel data window",
                        sat_mul(w, p.tile_y)});
    } else {
      const int lines = lines_per_chunk(p.compression);
      blocks.push_back({"chunks of " + std::to_string(lines) + " lines of the " +
                            std::to_string(w) + "-pixel data window",
                        sat_mul(w, lines)});
    }
    for (const Block& b : blocks) {
      if (b.pixels > limits_.max_pixels)
        return set_error(label(i) + b.what + " refused: " + std::to_string(b.pixels) +
                         " pixels (limit " + std::to_string(limits_.max_pixels) + " pixels)");
      const int64_t bytes = sat_mul(b.pixels, p.bytes_per_pixel);
      if (bytes > limits_.max_decoded_bytes)
        return set_error(label(i) + b.what + " refused: " + std::to_string(p.channels) +
                         " channels of " + std::to_string(p.bytes_per_pixel) +
                         " bytes per pixel decode to " + std::to_string(bytes) +
                         " bytes (limit " + std::to_string(limits_.max_decoded_bytes) + " bytes)");
    }
    return true;
  }

  Source& src_;
  std::string path_;
  ExrLimits limits_;
  std::string error_;
  bool multipart_ = false, tiled_flag_ = false, non_image_ = false;
  std::vector<PartWalk> parts_;
};

}  // namespace

ExrHeaderCheck check_exr_headers(const std::string& path, const ExrLimits& limits) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    ExrHeaderCheck out;
    out.error = path + ": cannot open: " + std::strerror(errno);
    return out;
  }
  ExrHeaderCheck out = check_exr_headers(fd, path, limits);
  ::close(fd);
  return out;
}

ExrHeaderCheck check_exr_headers(int fd, const std::string& path, const ExrLimits& limits) {
  ExrHeaderCheck out;
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    out.error = path + ": cannot stat: " + std::strerror(errno);
    return out;
  }
  out.file_bytes = int64_t(st.st_size);
  auto src = std::make_unique<Source>(fd, out.file_bytes);
  Walker(*src, path, limits).run(out);
  return out;
}

}  // namespace ssdo
