// Structural check of an OpenEXR file's headers against the file itself, before OpenEXR
// parses them.
//
// OpenEXR (3.1) trusts the sizes a header declares: a string attribute declaring 1.6 GB
// is allocated and zero-filled before the read fails, an opaque attribute likewise, and
// the chunk offset table of every part is sized from the data window, the tiling or the
// chunkCount attribute before a single offset is read. A damaged or hostile file of a
// few hundred bytes thereby costs gigabytes and seconds. check_exr_headers walks the
// headers the way OpenEXR reads them and refuses, naming the file, the part and the
// attribute:
// - an attribute whose value does not fit in the rest of the file, or whose declared size
//   differs from what OpenEXR's reader of that type consumes (OpenEXR reads fixed-size
//   types and channel lists regardless of the declared size: a mismatch would make it
//   read the rest of the header out of step with this walk);
// - a name of 255 characters or more (OpenEXR truncates it and reads on out of step);
// - a channel list with a sampling below 1, a tile description with a zero size or an
//   unknown level mode, an unknown compression, a data window of zero or negative size;
// - a chunk count (chunkCount attribute, else computed from the data window, compression
//   and tiling as OpenEXR does) whose offset table, 8 bytes per chunk, does not fit in the
//   file, and a chunkCount attribute that disagrees with the computed count;
// - an uncompressed image part whose pixels (every channel, as stored) do not fit in the
//   file.
// These hold for every complete, well-formed file, whatever its size.
//
// Opening the file already costs, for every part, a compressor sized for one chunk (the
// data window's width x the lines of a chunk x every channel) and a table of the bytes of
// every line; reading a part costs its whole data window, all channels (OpenEXR decodes
// the channels it is not asked for too), and a tiled part a row of tiles. So the resource
// limits (ExrLimits) apply to every part, before OpenEXR sees the file:
// - pixels: the data window, a chunk of lines, a tile and a row of tiles, each at most
//   max_pixels;
// - bytes: the same blocks with every channel as stored (half 2 bytes, float and uint 4),
//   each at most max_decoded_bytes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ssdo {

// The largest data window read by default, everywhere a frame is read (ssdo info, process,
// serve and their workers): 8192 x 8192.
constexpr int64_t kDefaultMaxPixels = int64_t(1) << 26;

// What the walk learnt of one part (the fields OpenEXR sizes its buffers from).
struct ExrPartLayout {
  std::string type;             // "scanlineimage" | "tiledimage" | "deepscanline" | "deeptile" | other
  int64_t min_x = 0, min_y = 0, max_x = 63, max_y = 63;  // dataWindow (OpenEXR's default)
  int compression = 3;          // OpenEXR's Compression enum (default ZIP)
  bool tiled = false;
  int64_t tile_x = 0, tile_y = 0;
  int64_t bytes_per_pixel = 0;  // every channel, as stored (half 2, float 4, uint 4)
  int channels = 0;
  int64_t chunks = 0;           // chunk offset table entries
  int64_t pixels() const { return (max_x - min_x + 1) * (max_y - min_y + 1); }
  // What reading the part decodes: its data window with every channel as stored.
  int64_t decoded_bytes() const { return pixels() * bytes_per_pixel; }
};

struct ExrLimits {
  int64_t max_pixels = kDefaultMaxPixels;
  int64_t max_decoded_bytes = int64_t(1) << 34;  // 64 float channels at kDefaultMaxPixels
};

struct ExrHeaderCheck {
  std::string error;  // empty when the headers are sound; else "PATH: ..." naming part and field
  std::vector<ExrPartLayout> parts;
  int64_t file_bytes = 0;
  int64_t header_bytes = 0;  // magic, version and every header, up to the offset tables
  bool ok() const { return error.empty(); }
};

ExrHeaderCheck check_exr_headers(const std::string& path, const ExrLimits& limits = {});
// The same of the file already open as `fd` (read with pread: its offset is left as it was);
// `path` names it in the messages.
ExrHeaderCheck check_exr_headers(int fd, const std::string& path, const ExrLimits& limits = {});

}  // namespace ssdo
