#include "formats/gbuffer_reader.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <climits>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <limits>
#include <memory>
#include <new>
#include <sstream>

#include <Imath/half.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/openexr.h>

#include "formats/camera_io.h"
#include "formats/channel_profiles.h"
#include "formats/exr_core.h"
#include "formats/exr_header_check.h"
#include "formats/half_samples.h"
#include "formats/exr_zip.h"
#include "kernels/normals.h"
#include "core/parallel.h"
#include "kernels/positions.h"

namespace ssdo {

namespace {

// What a failed OpenEXR read is called: OpenEXR passes an allocation that failed (e.g.
// under the worker's --memory-limit) on as an exception whose text is std::bad_alloc's.
const char* read_failure(const std::exception& e) {
  return std::strstr(e.what(), "bad_alloc") ? "out of memory" : "damaged or truncated file";
}

// Depth at or beyond this is background: renderers write "no hit" as a huge finite value
// (Cycles: 1e10, see /work/shared/gbuffers/README.md) rather than +inf.
constexpr float kBackgroundDepth = 1e9f;
// A stored normal shorter than this is "no normal" (Cycles writes (0, 0, 0) where it has
// none); unit normals in half precision are ~1 +- 1e-3.
constexpr float kMinNormalLength = 1e-6f;
// Non-standard header attributes carrying the clip distances next to worldToCamera /
// worldToNDC (written by write_outputs; OpenEXR has no standard attribute for them).
constexpr const char* kClipNearAttribute = "clipNear";
constexpr const char* kClipFarAttribute = "clipFar";

std::string type_name(Imf::PixelType t) {
  switch (t) {
    case Imf::HALF: return "half";
    case Imf::FLOAT: return "float";
    case Imf::UINT: return "uint";
    default: return "unknown";
  }
}

PixelBox box_of(const Imath::Box2i& b) { return {b.min.x, b.min.y, b.max.x, b.max.y}; }

std::string describe_box(const PixelBox& b) {
  std::ostringstream s;
  s << b.width() << "x" << b.height() << " at (" << b.min_x << ", " << b.min_y << ")";
  return s.str();
}

std::string space_name(Space s) {
  switch (s) {
    case Space::world: return "world";
    case Space::view: return "view";
    default: return "";
  }
}

// Everything known once the headers are read: the file, the channels to read, the pixel
// grid and the camera.
struct Prepared {
  std::string path;
  std::unique_ptr<Imf::MultiPartInputFile> file;
  std::vector<PartChannels> parts;
  ChannelResolution channels;
  PixelBox data, display;
  Camera camera;
  bool camera_has_world = false;  // sidecar or header: world_to_view is meaningful
  bool radial_depth = false;
  std::optional<float> background_depth;
  std::optional<std::string> sidecar_normal_space, sidecar_position_space;
};

// Which resolved inputs the options ask to read.
bool wanted(const ResolvedInput& r, const ReadOptions& o, bool lighting_from_passes) {
  if (r.input == "depth" || r.input == "normal") return true;
  if (r.input == "position") return o.read_positions;
  if (r.input == "albedo") return o.read_albedo || (o.read_lighting && lighting_from_passes);
  if (r.input == "lighting") return o.read_lighting;
  if (r.input == "diffdir") return o.read_lighting && lighting_from_passes;
  if (r.input.rfind("reference:", 0) == 0) return o.read_references;
  return false;
}

Space decide_space(Space resolved, const std::optional<std::string>& sidecar_says,
                   bool camera_has_world) {
  if (resolved != Space::automatic) return resolved;
  if (sidecar_says) return *sidecar_says == "world" ? Space::world : Space::view;
  // Generic N / P: world space when the camera knows where the world is (sidecar or
  // header matrices), view space under a bare --fov camera (whose world is the view).
  return camera_has_world ? Space::world : Space::view;
}

bool prepare(const std::string& path, const ReadOptions& options, ReadResult& result,
             Prepared& prep) {
  FrameInfo& info = result.info;
  info.path = path;
  prep.path = path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    result.error = path + ": no such file";
    return false;
  }
  if (!std::filesystem::is_regular_file(path, ec)) {
    result.error = path + ": not a regular file";
    return false;
  }
  // The headers against the file and the limits, before OpenEXR allocates from them
  // (formats/exr_header_check.h).
  const ExrHeaderCheck check =
      check_exr_headers(path, {options.max_pixels, options.max_decoded_bytes});
  if (!check.ok()) {
    result.error = check.error;
    return false;
  }
  const int threads = options.threads > 0 ? options.threads : Imf::globalThreadCount();
  // OpenEXR decodes on its process-wide pool; asking for N threads makes sure it has N.
  if (options.threads > 1 && Imf::globalThreadCount() < options.threads)
    Imf::setGlobalThreadCount(options.threads);
  try {
    prep.file = std::make_unique<Imf::MultiPartInputFile>(path.c_str(), threads);
  } catch (const std::exception& e) {
    result.error = path + ": cannot read the EXR header (" + read_failure(e) + "): " + e.what();
    return false;
  }
  const int n_parts = prep.file->parts();
  for (int i = 0; i < n_parts; ++i) {
    const Imf::Header& h = prep.file->header(i);
    PartChannels pc;
    pc.name = h.hasName() ? h.name() : std::string();
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
      pc.channels.push_back(it.name());
    info.parts.push_back(pc.name);
    prep.parts.push_back(std::move(pc));
  }

  // Channels.
  std::string error;
  auto resolved = resolve_channels(path, prep.parts, options, &error);
  if (!resolved) {
    result.error = error;
    return false;
  }
  prep.channels = *resolved;
  const int part = prep.channels.part;
  const Imf::Header& header = prep.file->header(part);
  info.part = prep.parts[part].name;
  info.profile = prep.channels.profile;
  info.layer = prep.channels.layer;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
    info.channels.push_back(std::string(it.name()) + " (" + type_name(it.channel().type) + ")");
  prep.data = box_of(header.dataWindow());
  prep.display = box_of(header.displayWindow());
  info.width_px = int(std::min<int64_t>(prep.data.width(), INT_MAX));
  info.height_px = int(std::min<int64_t>(prep.data.height(), INT_MAX));
  info.data_x = prep.data.min_x;
  info.data_y = prep.data.min_y;
  info.display_width_px = int(std::min<int64_t>(prep.display.width(), INT_MAX));
  info.display_height_px = int(std::min<int64_t>(prep.display.height(), INT_MAX));
  info.display_x = prep.display.min_x;
  info.display_y = prep.display.min_y;
  const std::string part_label =
      prep.parts.size() > 1 ? " (part \"" + prep.parts[part].name + "\")" : "";

  // Absurd sizes are refused before anything is allocated.
  if (prep.data.width() <= 0 || prep.data.height() <= 0 || prep.data.width() > INT_MAX / 16 ||
      prep.data.height() > INT_MAX / 16 ||
      prep.data.width() * prep.data.height() > options.max_pixels) {
    result.error = path + part_label + ": data window " + describe_box(prep.data) +
                   " refused (limit " + std::to_string(options.max_pixels) + " pixels)";
    return false;
  }

  // Every part a used channel comes from must share the depth part's pixel grid.
  const bool lighting_from_passes =
      !prep.channels.find("lighting") && prep.channels.find("albedo") &&
      prep.channels.find("diffdir");
  for (const auto& r : prep.channels.inputs) {
    if (!wanted(r, options, lighting_from_passes)) continue;
    const Imf::Header& h = prep.file->header(r.part);
    if (h.type() == Imf::DEEPSCANLINE || h.type() == Imf::DEEPTILE) {
      result.error = path + ": part \"" + prep.parts[r.part].name +
                     "\" holds deep data, which a G-buffer cannot use";
      return false;
    }
    if (box_of(h.dataWindow()) != prep.data) {
      result.error = path + ": parts of different sizes: " + r.input + " channels in part \"" +
                     prep.parts[r.part].name + "\" have data window " +
                     describe_box(box_of(h.dataWindow())) + ", depth in part \"" +
                     prep.parts[part].name + "\" has " + describe_box(prep.data);
      return false;
    }
    for (const auto& c : r.channels) {
      const Imf::Channel* ch = h.channels().findChannel(c);
      if (ch && (ch->xSampling != 1 || ch->ySampling != 1)) {
        result.error = path + part_label + ": channel " + c + " is subsampled (" +
                       std::to_string(ch->xSampling) + "x" + std::to_string(ch->ySampling) +
                       "), which a G-buffer cannot use";
        return false;
      }
    }
  }

  // Camera: sidecar, then header matrices, then --fov.
  const std::string sidecar =
      options.camera_json.empty() ? sidecar_path_for(path) : options.camera_json;
  std::optional<SidecarCamera> side;
  if (!options.camera_json.empty() || std::filesystem::exists(sidecar, ec)) {
    side = read_camera_sidecar(sidecar, &error);
    if (!side) {
      result.error = path + ": " + error;
      return false;
    }
    if (side->width_px == prep.display.width() && side->height_px == prep.display.height()) {
      prep.camera = side->camera;
      prep.camera.view_to_clip =
          projection_for_data_window(side->camera.view_to_clip, prep.display, prep.data);
    } else if (side->width_px == prep.data.width() && side->height_px == prep.data.height()) {
      prep.camera = side->camera;
      info.notes.push_back("sidecar size matches the data window, not the display window");
    } else {
      result.error = path + ": camera sidecar " + sidecar + " is for " +
                     std::to_string(side->width_px) + "x" + std::to_string(side->height_px) +
                     " pixels, but the frame's display window is " + describe_box(prep.display) +
                     " and its data window " + describe_box(prep.data);
      return false;
    }
    prep.camera.width_px = int(prep.data.width());
    prep.camera.height_px = int(prep.data.height());
    prep.camera_has_world = true;
    info.camera_source = "sidecar " + sidecar;
    info.ao_distance_world = side->ao_distance_world;
    prep.background_depth = side->background_depth;
    prep.sidecar_normal_space = side->normal_space;
    prep.sidecar_position_space = side->position_space;
    if (options.depth_kind == DepthKind::automatic && side->depth_kind)
      prep.radial_depth = *side->depth_kind == "radial";
  } else {
    // The depth part's header first, then any other part's.
    std::vector<int> order{part};
    for (int i = 0; i < n_parts; ++i)
      if (i != part) order.push_back(i);
    bool found = false;
    for (int i : order) {
      const Imf::Header& h = prep.file->header(i);
      if (!Imf::hasWorldToCamera(h) || !Imf::hasWorldToNDC(h)) continue;
      ExrCameraMatrices m;
      const Imath::M44f& w2c = Imf::worldToCamera(h);
      const Imath::M44f& w2n = Imf::worldToNDC(h);
      // Same 16 floats in the same order: Imath row-vector == glm column-vector form.
      std::copy(&w2c.x[0][0], &w2c.x[0][0] + 16, &m.world_to_camera[0][0]);
      std::copy(&w2n.x[0][0], &w2n.x[0][0] + 16, &m.world_to_ndc[0][0]);
      float near_view = 0.0f, far_view = 0.0f;
      if (auto* a = h.findTypedAttribute<Imf::FloatAttribute>(kClipNearAttribute))
        near_view = a->value();
      if (auto* a = h.findTypedAttribute<Imf::FloatAttribute>(kClipFarAttribute))
        far_view = a->value();
      std::string note;
      // The matrices refer to this part's display window; the grid is the depth part's.
      auto cam = camera_from_exr_matrices(m, box_of(h.displayWindow()), prep.data, near_view,
                                          far_view, &error, &note);
      if (!cam) {
        result.error = path + ": " + error;
        return false;
      }
      prep.camera = *cam;
      prep.camera_has_world = true;
      info.camera_source = "header worldToCamera/worldToNDC";
      if (n_parts > 1) info.camera_source += " (part \"" + prep.parts[i].name + "\")";
      info.notes.push_back(note);
      found = true;
      break;
    }
    if (!found) {
      if (!options.fov_x_deg) {
        result.error =
            path + ": no camera: give a JSON sidecar (" + sidecar +
            " or an explicit camera JSON path), store worldToCamera and worldToNDC "
            "attributes in the EXR header, or pass a horizontal field of view (--fov DEGREES)";
        return false;
      }
      const float fov = *options.fov_x_deg;
      if (!(fov > 0.0f && fov < 180.0f)) {
        result.error = path + ": field of view " + std::to_string(fov) +
                       " degrees is outside (0, 180)";
        return false;
      }
      // The field of view spans the display window (the full image), like a sidecar.
      Camera cam = Camera::from_fov_x(int(prep.display.width()), int(prep.display.height()), fov);
      cam.view_to_clip = projection_for_data_window(cam.view_to_clip, prep.display, prep.data);
      cam.width_px = int(prep.data.width());
      cam.height_px = int(prep.data.height());
      cam.near_view = cam.far_view = 0.0f;  // defaults of from_fov_x, not known clips
      prep.camera = cam;
      std::ostringstream source;
      source << "--fov " << fov;
      info.camera_source = source.str();
      if (prep.display != prep.data)
        info.notes.push_back("field of view spans the display window; the data window sees a part of it");
    }
  }
  if (options.fov_x_deg && prep.camera_has_world)
    info.notes.push_back("the given field of view is ignored: the frame's camera (" +
                         info.camera_source + ") takes precedence");
  if (options.depth_kind != DepthKind::automatic)
    prep.radial_depth = options.depth_kind == DepthKind::radial;
  else if (!side || !side->depth_kind)
    info.notes.push_back("depth kind not stated by the file or sidecar: planar assumed");
  info.depth_kind = prep.radial_depth ? "radial" : "planar";
  info.fov_x_deg = prep.camera.fov_x_deg();
  info.fov_y_deg = prep.camera.fov_y_deg();
  info.near_view = prep.camera.near_view;
  info.far_view = prep.camera.far_view;

  // What became what.
  for (auto& r : prep.channels.inputs) {
    if (r.input == "normal")
      r.space = decide_space(r.space, prep.sidecar_normal_space, prep.camera_has_world);
    if (r.input == "position")
      r.space = decide_space(r.space, prep.sidecar_position_space, prep.camera_has_world);
  }
  for (const auto& r : prep.channels.inputs) {
    if (!wanted(r, options, lighting_from_passes) || r.input == "diffdir") continue;
    if (r.input == "albedo" && !options.read_albedo) continue;
    std::string channels = r.describe();
    if (prep.parts.size() > 1) channels = prep.parts[r.part].name + ":" + channels;
    info.uses.push_back({r.input, channels, space_name(r.space)});
  }
  if (options.read_lighting && lighting_from_passes)
    info.uses.push_back({"lighting",
                         prep.channels.find("albedo")->describe() + " * " +
                             prep.channels.find("diffdir")->describe() +
                             " (albedo x direct irradiance = sender radiance)",
                         ""});
  if (!prep.channels.find("normal")) info.normals_reconstructed = true;
  return true;
}

// ---------------------------------------------------------------------------------------
// ZIP / ZIPS / uncompressed scanline parts without OpenEXR's decoder (ZipDecoder::libdeflate).
//
// File layout (OpenEXR "File Layout", scan line images; "Technical Introduction", data
// compression): a chunk holds the lines [min_y + i * lines, min_y + (i + 1) * lines) of the
// data window (16 lines per chunk for ZIP, 1 for ZIPS and NO_COMPRESSION; the last chunk
// may hold fewer); its pixels, packed, are per line each channel in the channel list's
// (name) order, each sample little-endian (HALF 2 bytes, FLOAT and UINT 4). A chunk whose
// stored size equals its packed size is stored as is, whatever the part's compression.
// The offset table is indexed by y whatever the line order, which only orders the chunks
// in the file.

// One channel read into a float image.
struct ChannelTarget {
  std::string channel;
  float* first;          // the data window's top-left pixel
  size_t pixel_floats;   // floats between neighbouring pixels (the image's channel count)
  size_t row_bytes;      // bytes between rows (cv::Mat step)
};

// A wanted channel found in the part's channel list.
struct ZipChannel {
  const ChannelTarget* target;
  exr_pixel_type_t type;
  size_t line_offset_bytes;  // where its samples start in a packed line
};

struct ZipPlan {
  exr_compression_t compression = EXR_COMPRESSION_NONE;
  int lines_per_chunk = 1;
  int chunks = 0;
  size_t line_bytes = 0;  // one packed line, every channel
  std::vector<ZipChannel> channels;
};

// Opens the file with OpenEXRCore; false (the caller uses OpenEXR's decoder) when it cannot.
// The headers already passed check_exr_headers and OpenEXR's own parser.
bool open_core(const std::string& path, exr_core::Context& file) {
  exr_context_initializer_t init = exr_core::quiet_initializer();
  // A damaged offset table is an error here, never a scan of the file for chunks.
  init.flags = EXR_CONTEXT_FLAG_SILENT_HEADER_PARSE | EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
  if (exr_start_read(file.out(), path.c_str(), &init) != EXR_ERR_SUCCESS) {
    file.finish();
    return false;
  }
  return true;
}

// The chunk layout of a part this path decodes; nullopt sends the part to OpenEXR (tiled,
// deep, another compression, subsampled channels, a wanted uint channel, or any header
// value OpenEXRCore and OpenEXR's reader disagree on).
std::optional<ZipPlan> plan_zip_part(exr_const_context_t context, int part, const PixelBox& data,
                                     const std::vector<ChannelTarget>& targets) {
  if constexpr (std::endian::native != std::endian::little) return std::nullopt;
  exr_storage_t storage;
  exr_compression_t compression;
  exr_attr_box2i_t window;
  const exr_attr_chlist_t* list = nullptr;
  int32_t lines = 0, chunks = 0;
  if (exr_get_storage(context, part, &storage) != EXR_ERR_SUCCESS ||
      storage != EXR_STORAGE_SCANLINE ||
      exr_get_compression(context, part, &compression) != EXR_ERR_SUCCESS ||
      (compression != EXR_COMPRESSION_NONE && compression != EXR_COMPRESSION_ZIP &&
       compression != EXR_COMPRESSION_ZIPS) ||
      exr_get_data_window(context, part, &window) != EXR_ERR_SUCCESS ||
      exr_get_channels(context, part, &list) != EXR_ERR_SUCCESS || !list ||
      exr_get_scanlines_per_chunk(context, part, &lines) != EXR_ERR_SUCCESS ||
      exr_get_chunk_count(context, part, &chunks) != EXR_ERR_SUCCESS)
    return std::nullopt;
  if (window.min.x != data.min_x || window.min.y != data.min_y || window.max.x != data.max_x ||
      window.max.y != data.max_y)
    return std::nullopt;
  const int64_t width = data.width(), height = data.height();
  const int expected_lines = compression == EXR_COMPRESSION_ZIP ? 16 : 1;
  if (lines != expected_lines || chunks != (height + lines - 1) / lines) return std::nullopt;
  ZipPlan plan;
  plan.compression = compression;
  plan.lines_per_chunk = lines;
  plan.chunks = chunks;
  // Offsets of every channel in a packed line, in the list's order.
  std::vector<size_t> offsets;
  int64_t line_bytes = 0;
  for (int c = 0; c < list->num_channels; ++c) {
    const exr_attr_chlist_entry_t& e = list->entries[c];
    if (e.x_sampling != 1 || e.y_sampling != 1) return std::nullopt;
    int64_t sample_bytes = 0;
    switch (e.pixel_type) {
      case EXR_PIXEL_HALF: sample_bytes = 2; break;
      case EXR_PIXEL_FLOAT:
      case EXR_PIXEL_UINT: sample_bytes = 4; break;
      default: return std::nullopt;
    }
    offsets.push_back(size_t(line_bytes));
    // The header check bounds a chunk's bytes (ExrLimits); this only keeps the sums exact.
    if (width > (std::numeric_limits<int64_t>::max() / 64 - line_bytes) / sample_bytes)
      return std::nullopt;
    line_bytes += width * sample_bytes;
  }
  plan.line_bytes = size_t(line_bytes);
  for (const ChannelTarget& t : targets) {
    int found = -1;
    for (int c = 0; c < list->num_channels && found < 0; ++c) {
      const exr_attr_string_t& name = list->entries[c].name;
      if (name.length >= 0 && size_t(name.length) == t.channel.size() &&
          std::memcmp(name.str, t.channel.data(), t.channel.size()) == 0)
        found = c;
    }
    // A channel missing from the file is OpenEXR's to fill; uint samples OpenEXR's to convert.
    if (found < 0 || list->entries[found].pixel_type == EXR_PIXEL_UINT) return std::nullopt;
    plan.channels.push_back({&t, list->entries[found].pixel_type, offsets[size_t(found)]});
  }
  return plan;
}

// Converts `width` samples of one packed line to float, exactly as OpenEXR does: half as
// Imath converts it (formats/half_samples.h), float as is.
void convert_samples(const uint8_t* from, exr_pixel_type_t type, int64_t width, float* to,
                     size_t pixel_floats) {
  if (type == EXR_PIXEL_HALF) {
    half_samples::to_float(from, width, to, pixel_floats);
  } else {
    for (int64_t x = 0; x < width; ++x)
      std::memcpy(&to[size_t(x) * pixel_floats], from + 4 * x, 4);
  }
}

// Reads, inflates and converts every chunk of the part; throws on the first damaged chunk
// (the lowest scanline, whatever the thread count), naming the part and the scanline.
void read_zip_part(exr_const_context_t context, int part, const std::string& part_name,
                   bool multi_part, const PixelBox& data, const ZipPlan& plan, int threads) {
  const int64_t width = data.width();
  std::vector<std::string> errors(size_t(plan.chunks));
  std::atomic<int> first_failed{plan.chunks};
  std::atomic<bool> out_of_memory{false};
  auto fail = [&](int chunk, std::string message) {
    errors[size_t(chunk)] = std::move(message);
    int seen = first_failed.load();
    while (chunk < seen && !first_failed.compare_exchange_weak(seen, chunk)) {
    }
  };
  auto read_chunk = [&](int chunk, std::vector<uint8_t>& stored, std::vector<uint8_t>& packed) {
    const int y = int(data.min_y + int64_t(chunk) * plan.lines_per_chunk);
    const int lines = int(std::min<int64_t>(plan.lines_per_chunk, data.max_y - y + 1));
    exr_chunk_info_t info{};
    exr_core::forget_error();
    if (const exr_result_t rv = exr_read_scanline_chunk_info(context, part, y, &info);
        rv != EXR_ERR_SUCCESS) {
      fail(chunk, "cannot locate the chunk (" + exr_core::error_text(rv) + ")");
      return;
    }
    const uint64_t expected = uint64_t(lines) * plan.line_bytes;
    // Core derives these from the header; checked all the same, since the conversion below
    // writes exactly `lines` rows of the images from exactly `expected` bytes.
    if (info.start_y != y || info.height != lines || info.width != width ||
        info.compression != uint8_t(plan.compression) || info.unpacked_size != expected) {
      fail(chunk, "chunk layout disagrees with the header (" + std::to_string(info.height) +
                      " lines from " + std::to_string(info.start_y) + ", " +
                      std::to_string(info.unpacked_size) + " bytes; expected " +
                      std::to_string(lines) + " lines from " + std::to_string(y) + ", " +
                      std::to_string(expected) + " bytes)");
      return;
    }
    // A stored chunk is never larger than its pixels: the format stores the pixels as they
    // are when compression does not make them smaller, and uncompressed parts always.
    if (info.packed_size > expected ||
        (plan.compression == EXR_COMPRESSION_NONE && info.packed_size != expected) ||
        (info.packed_size == 0 && expected > 0)) {
      fail(chunk, "chunk of " + std::to_string(info.packed_size) + " bytes for " +
                      std::to_string(expected) + " bytes of pixels");
      return;
    }
    // Core checked packed_size against the file's size: this allocation is bounded by it.
    stored.resize(size_t(info.packed_size));
    exr_core::forget_error();
    if (const exr_result_t rv = exr_read_chunk(context, part, &info, stored.data());
        rv != EXR_ERR_SUCCESS) {
      fail(chunk, "cannot read the chunk (" + exr_core::error_text(rv) + ")");
      return;
    }
    const uint8_t* pixels = stored.data();
    if (info.packed_size < expected) {
      packed.resize(size_t(expected));
      if (!exr_zip::decompress(stored, packed)) {
        fail(chunk, "ZIP data of " + std::to_string(info.packed_size) +
                        " bytes does not inflate to the chunk's " + std::to_string(expected) +
                        " bytes");
        return;
      }
      pixels = packed.data();
    }
    for (int line = 0; line < lines; ++line) {
      const uint8_t* from = pixels + size_t(line) * plan.line_bytes;
      const size_t row = size_t(y - data.min_y + line);
      for (const ZipChannel& c : plan.channels) {
        const ChannelTarget& t = *c.target;
        float* to = reinterpret_cast<float*>(reinterpret_cast<uint8_t*>(t.first) + row * t.row_bytes);
        convert_samples(from + c.line_offset_bytes, c.type, width, to, t.pixel_floats);
      }
    }
  };
  // One strip per chunk (16 or 1 lines): the chunks are the unit of work.
  parallel_rows(cv::Range(0, plan.chunks), threads, [&](const cv::Range& range) {
    std::vector<uint8_t> stored, packed;
    for (int chunk = range.start; chunk < range.end; ++chunk) {
      // Chunks after a damaged one are not worth reading; those before it still decide which
      // error is reported.
      if (chunk > first_failed.load()) break;
      try {
        read_chunk(chunk, stored, packed);
      } catch (const std::bad_alloc&) {
        out_of_memory = true;
        fail(chunk, "out of memory");
      } catch (const std::exception& e) {
        fail(chunk, e.what());
      }
    }
  }, 1);
  if (out_of_memory) throw std::bad_alloc();
  const int chunk = first_failed.load();
  if (chunk < plan.chunks) {
    std::string where = multi_part ? "part \"" + part_name + "\", " : std::string();
    throw std::runtime_error(where + "scanline " +
                             std::to_string(data.min_y + int64_t(chunk) * plan.lines_per_chunk) +
                             ": " + errors[size_t(chunk)]);
  }
}

struct Images {
  cv::Mat depth, normal, position, albedo, diffdir, lighting;
  std::map<std::string, cv::Mat> references;
};

// Reads the wanted channels of each part straight into the float images: one slice per
// channel, interleaved by the slice strides; OpenEXR (or, for ZIP parts, read_zip_part)
// converts half to float.
void read_pixels(Prepared& prep, const ReadOptions& options, bool lighting_from_passes,
                 Images& img, cv::Size size) {
  std::map<int, Imf::FrameBuffer> buffers;
  std::map<int, std::vector<ChannelTarget>> targets;  // the same slices, for read_zip_part
  std::map<std::string, cv::Mat*> read_into;
  std::vector<std::pair<cv::Mat*, cv::Mat*>> aliases;  // (alias, image read)
  std::map<std::string, std::pair<cv::Mat*, int>> first_use;  // "part:channel" -> image, component
  struct Copy {
    cv::Mat* from;
    int from_component;
    cv::Mat* to;
    int to_component;
  };
  std::vector<Copy> copies;
  const Imath::Box2i window(Imath::V2i(prep.data.min_x, prep.data.min_y),
                            Imath::V2i(prep.data.max_x, prep.data.max_y));
  for (const auto& r : prep.channels.inputs) {
    if (!wanted(r, options, lighting_from_passes)) continue;
    cv::Mat* target = nullptr;
    if (r.input == "depth") target = &img.depth;
    else if (r.input == "normal") target = &img.normal;
    else if (r.input == "position") target = &img.position;
    else if (r.input == "albedo") target = &img.albedo;
    else if (r.input == "diffdir") target = &img.diffdir;
    else if (r.input == "lighting") target = &img.lighting;
    else target = &img.references[r.input.substr(std::string("reference:").size())];
    // Two inputs on the same channels (DiffDir as lighting factor and as reference) share
    // one image: OpenEXR takes one slice per channel name.
    const std::string key = std::to_string(r.part) + ":" + join_names(r.channels);
    if (auto it = read_into.find(key); it != read_into.end()) {
      aliases.emplace_back(target, it->second);
      continue;
    }
    read_into[key] = target;
    const int n = int(r.channels.size());
    target->create(size, CV_32FC(n));
    for (int c = 0; c < n; ++c) {
      // A channel already read for another input (a mapped reference on one component of
      // the lighting layer, say) is copied after reading.
      const std::string channel_key = std::to_string(r.part) + ":" + r.channels[c];
      if (auto it = first_use.find(channel_key); it != first_use.end()) {
        copies.push_back({it->second.first, it->second.second, target, c});
        continue;
      }
      first_use[channel_key] = {target, c};
      buffers[r.part].insert(r.channels[c],
                             Imf::Slice::Make(Imf::FLOAT, target->ptr<float>() + c, window,
                                              sizeof(float) * n, target->step[0]));
      targets[r.part].push_back({r.channels[c], target->ptr<float>() + c, size_t(n),
                                 target->step[0]});
    }
  }
  exr_core::Context core;
  bool core_tried = false;
  for (auto& [part, fb] : buffers) {
    if (!prep.file->partComplete(part))
      throw std::runtime_error("incomplete or truncated file: part \"" + prep.parts[part].name +
                               "\" is missing pixel data");
    if (options.zip_decoder == ZipDecoder::libdeflate) {
      if (!core_tried) {
        core_tried = true;
        open_core(prep.path, core);
      }
      if (core.get()) {
        if (auto plan = plan_zip_part(core.get(), part, prep.data, targets[part])) {
          read_zip_part(core.get(), part, prep.parts[part].name, prep.parts.size() > 1,
                        prep.data, *plan, options.threads);
          continue;
        }
      }
    }
    Imf::InputPart in(*prep.file, part);
    in.setFrameBuffer(fb);
    in.readPixels(prep.data.min_y, prep.data.max_y);
  }
  for (const Copy& c : copies) {
    const int pair[2] = {c.from_component, c.to_component};
    cv::mixChannels(c.from, 1, c.to, 1, pair, 1);
  }
  for (auto& [alias, source] : aliases) *alias = *source;
}

void set_nonfinite_to_zero(cv::Mat& m) {
  if (m.empty()) return;
  float* p = m.ptr<float>();
  const size_t n = m.total() * m.channels();
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) p[i] = 0.0f;
}

// One row's share of what read_gbuffer reports.
struct RowCounts {
  int64_t foreground = 0, nonfinite = 0, repaired = 0;
  float depth_min = std::numeric_limits<float>::infinity();
  float depth_max = -std::numeric_limits<float>::infinity();
};

// What the pass after reading needs besides the row's pixels (see foreground_row).
struct ForegroundPass {
  int width = 0;
  float far_view = 0.0f;
  bool has_background = false;
  float background = 0.0f;
  bool radial = false, perspective = false, normals_world = false;
  glm::mat3 normal_to_view{1.0f};
  glm::vec3 ray_step_x{0.0f};
};

// The pass after reading, one row: depth (radial -> planar) classified as foreground or
// not, normals to view space, unit length and facing the camera. `ray_row` is the eye ray
// through the row's first pixel centre; `normal` and `repair` are null without normals.
// Background and unusable pixels get depth +inf, mask 0 and normal (0, 0, 0); foreground
// pixels mask 255, and repair 1 where the normal is (0, 0, 0). `pass` is taken by value:
// the mask's byte stores may alias anything behind a reference, which would be reloaded
// per pixel.
RowCounts foreground_row(const ForegroundPass pass, const glm::vec3 ray_row, float* depth,
                         uint8_t* mask, cv::Vec3f* normal, uint8_t* repair) {
  const float inf = std::numeric_limits<float>::infinity();
  RowCounts counts;
  // One pixel, every case.
  auto pixel = [&](int x) {
    float d = depth[x];
    bool nonfinite = !std::isfinite(d);
    glm::vec3 n(0.0f);
    if (normal) {
      n = glm::vec3(normal[x][0], normal[x][1], normal[x][2]);
      if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z)) nonfinite = true;
    }
    // The eye ray through the pixel centre (length arbitrary, z = -1 in perspective).
    const glm::vec3 ray =
        pass.perspective ? ray_row + float(x) * pass.ray_step_x : glm::vec3(0.0f, 0.0f, -1.0f);
    // Radial distance from the eye -> planar depth along -Z: d_planar = d cos(angle
    // to the axis) = d / |ray| for a ray with z = -1.
    if (pass.radial && !nonfinite && pass.perspective) d /= glm::length(ray);
    const bool foreground = !nonfinite && d > 0.0f && d < kBackgroundDepth &&
                            !(pass.far_view > 0.0f && d > pass.far_view) &&
                            !(pass.has_background && depth[x] == pass.background);
    if (!foreground) {
      counts.nonfinite += nonfinite ? 1 : 0;
      depth[x] = inf;
      mask[x] = 0;
      if (normal) normal[x] = cv::Vec3f(0, 0, 0);
      return;
    }
    depth[x] = d;
    mask[x] = 255;
    ++counts.foreground;
    counts.depth_min = std::min(counts.depth_min, d);
    counts.depth_max = std::max(counts.depth_max, d);
    if (normal) {
      if (pass.normals_world) n = pass.normal_to_view * n;
      const float len = glm::length(n);
      if (!(len > kMinNormalLength)) {
        repair[x] = 1;
        ++counts.repaired;
        normal[x] = cv::Vec3f(0, 0, 0);
        return;
      }
      n /= len;
      // Face the camera: a normal pointing away from the eye (back face, or a
      // renderer that does not flip shading normals) is turned around, since the
      // kernels integrate over the visible side's hemisphere.
      if (glm::dot(n, ray) > 0.0f) n = -n;
      normal[x] = cv::Vec3f(n.x, n.y, n.z);
    }
  };
  int x = 0;
#if defined(__SSE2__)
  // Four pixels at a time while all four are foreground with a usable normal (nearly every
  // group of a rendered frame); any other group goes pixel by pixel. The operations are
  // `pixel`'s, in its order and without contraction (SSE2 has no FMA), so the bits are its.
  if (normal) {
    const __m128 zero = _mm_setzero_ps();
    const __m128 magnitude_bits = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 infinity = _mm_set1_ps(inf);
    const __m128 sign_bit = _mm_set1_ps(-0.0f);
    const __m128 background_depth = _mm_set1_ps(kBackgroundDepth);
    // No far clip: +inf, which no depth exceeds; no background value: NaN, which no depth
    // equals.
    const __m128 far_view = _mm_set1_ps(pass.far_view > 0.0f ? pass.far_view : inf);
    const __m128 background = _mm_set1_ps(
        pass.has_background ? pass.background : std::numeric_limits<float>::quiet_NaN());
    const __m128 min_length = _mm_set1_ps(kMinNormalLength);
    const glm::mat3& m = pass.normal_to_view;
    const __m128 m00 = _mm_set1_ps(m[0][0]), m10 = _mm_set1_ps(m[1][0]), m20 = _mm_set1_ps(m[2][0]);
    const __m128 m01 = _mm_set1_ps(m[0][1]), m11 = _mm_set1_ps(m[1][1]), m21 = _mm_set1_ps(m[2][1]);
    const __m128 m02 = _mm_set1_ps(m[0][2]), m12 = _mm_set1_ps(m[1][2]), m22 = _mm_set1_ps(m[2][2]);
    const __m128 ray_row_x = _mm_set1_ps(ray_row.x), ray_row_y = _mm_set1_ps(ray_row.y),
                 ray_row_z = _mm_set1_ps(ray_row.z);
    const __m128 step_x = _mm_set1_ps(pass.ray_step_x.x), step_y = _mm_set1_ps(pass.ray_step_x.y),
                 step_z = _mm_set1_ps(pass.ray_step_x.z);
    const __m128 lanes = _mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f);
    __m128 depth_min = infinity, depth_max = _mm_set1_ps(-inf);
    for (; x + 4 <= pass.width; x += 4) {
      const __m128 stored = _mm_loadu_ps(depth + x);
      // (x0 y0 z0 x1) (y1 z1 x2 y2) (z2 x3 y3 z3) -> (x0 x1 x2 x3) (y0 ..) (z0 ..).
      float* n_at = &normal[x][0];
      const __m128 a = _mm_loadu_ps(n_at), b = _mm_loadu_ps(n_at + 4), c = _mm_loadu_ps(n_at + 8);
      __m128 nx = _mm_shuffle_ps(a, _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 1, 2, 2)),
                                 _MM_SHUFFLE(2, 0, 3, 0));
      __m128 ny = _mm_shuffle_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(0, 0, 1, 1)),
                                 _mm_shuffle_ps(b, c, _MM_SHUFFLE(2, 2, 3, 3)),
                                 _MM_SHUFFLE(2, 0, 2, 0));
      __m128 nz = _mm_shuffle_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(1, 1, 2, 2)), c,
                                 _MM_SHUFFLE(3, 0, 2, 0));
      // Finite: |v| < inf (false for NaN).
      __m128 usable = _mm_and_ps(
          _mm_and_ps(_mm_cmplt_ps(_mm_and_ps(stored, magnitude_bits), infinity),
                     _mm_cmplt_ps(_mm_and_ps(nx, magnitude_bits), infinity)),
          _mm_and_ps(_mm_cmplt_ps(_mm_and_ps(ny, magnitude_bits), infinity),
                     _mm_cmplt_ps(_mm_and_ps(nz, magnitude_bits), infinity)));
      __m128 ray_x = zero, ray_y = zero, ray_z = _mm_set1_ps(-1.0f);
      if (pass.perspective) {
        // float(x) + lane is float(x + lane): integers this small are exact.
        const __m128 at = _mm_add_ps(_mm_set1_ps(float(x)), lanes);
        ray_x = _mm_add_ps(ray_row_x, _mm_mul_ps(at, step_x));
        ray_y = _mm_add_ps(ray_row_y, _mm_mul_ps(at, step_y));
        ray_z = _mm_add_ps(ray_row_z, _mm_mul_ps(at, step_z));
      }
      __m128 d = stored;
      if (pass.radial && pass.perspective)
        d = _mm_div_ps(d, _mm_sqrt_ps(_mm_add_ps(
                              _mm_add_ps(_mm_mul_ps(ray_x, ray_x), _mm_mul_ps(ray_y, ray_y)),
                              _mm_mul_ps(ray_z, ray_z))));
      usable = _mm_and_ps(usable, _mm_and_ps(_mm_cmpgt_ps(d, zero), _mm_cmplt_ps(d, background_depth)));
      usable = _mm_andnot_ps(_mm_or_ps(_mm_cmpgt_ps(d, far_view), _mm_cmpeq_ps(stored, background)),
                             usable);
      if (pass.normals_world) {
        const __m128 vx = nx, vy = ny, vz = nz;
        nx = _mm_add_ps(_mm_add_ps(_mm_mul_ps(m00, vx), _mm_mul_ps(m10, vy)), _mm_mul_ps(m20, vz));
        ny = _mm_add_ps(_mm_add_ps(_mm_mul_ps(m01, vx), _mm_mul_ps(m11, vy)), _mm_mul_ps(m21, vz));
        nz = _mm_add_ps(_mm_add_ps(_mm_mul_ps(m02, vx), _mm_mul_ps(m12, vy)), _mm_mul_ps(m22, vz));
      }
      const __m128 len = _mm_sqrt_ps(
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, nx), _mm_mul_ps(ny, ny)), _mm_mul_ps(nz, nz)));
      usable = _mm_and_ps(usable, _mm_cmpgt_ps(len, min_length));
      if (_mm_movemask_ps(usable) != 0xf) {
        for (int i = 0; i < 4; ++i) pixel(x + i);
        continue;
      }
      nx = _mm_div_ps(nx, len);
      ny = _mm_div_ps(ny, len);
      nz = _mm_div_ps(nz, len);
      const __m128 facing = _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, ray_x), _mm_mul_ps(ny, ray_y)),
                                       _mm_mul_ps(nz, ray_z));
      const __m128 flip = _mm_and_ps(_mm_cmpgt_ps(facing, zero), sign_bit);
      nx = _mm_xor_ps(nx, flip);
      ny = _mm_xor_ps(ny, flip);
      nz = _mm_xor_ps(nz, flip);
      _mm_storeu_ps(depth + x, d);
      std::memset(mask + x, 255, 4);
      // And back: (x0 y0 z0 x1) (y1 z1 x2 y2) (z2 x3 y3 z3).
      const __m128 xy = _mm_shuffle_ps(nx, ny, _MM_SHUFFLE(0, 0, 0, 0));  // x0 x0 y0 y0
      const __m128 zx = _mm_shuffle_ps(nz, nx, _MM_SHUFFLE(1, 1, 0, 0));  // z0 z0 x1 x1
      const __m128 yz = _mm_shuffle_ps(ny, nz, _MM_SHUFFLE(1, 1, 1, 1));  // y1 y1 z1 z1
      const __m128 xy2 = _mm_shuffle_ps(nx, ny, _MM_SHUFFLE(2, 2, 2, 2));  // x2 x2 y2 y2
      const __m128 zx3 = _mm_shuffle_ps(nz, nx, _MM_SHUFFLE(3, 3, 2, 2));  // z2 z2 x3 x3
      const __m128 yz3 = _mm_shuffle_ps(ny, nz, _MM_SHUFFLE(3, 3, 3, 3));  // y3 y3 z3 z3
      _mm_storeu_ps(n_at, _mm_shuffle_ps(xy, zx, _MM_SHUFFLE(2, 0, 2, 0)));
      _mm_storeu_ps(n_at + 4, _mm_shuffle_ps(yz, xy2, _MM_SHUFFLE(2, 0, 2, 0)));
      _mm_storeu_ps(n_at + 8, _mm_shuffle_ps(zx3, yz3, _MM_SHUFFLE(2, 0, 2, 0)));
      counts.foreground += 4;
      depth_min = _mm_min_ps(depth_min, d);
      depth_max = _mm_max_ps(depth_max, d);
    }
    // Foreground depths are finite and positive: the extremes do not depend on the order.
    alignas(16) float lo[4], hi[4];
    _mm_store_ps(lo, depth_min);
    _mm_store_ps(hi, depth_max);
    for (int i = 0; i < 4; ++i) {
      counts.depth_min = std::min(counts.depth_min, lo[i]);
      counts.depth_max = std::max(counts.depth_max, hi[i]);
    }
  }
#endif
  for (; x < pass.width; ++x) pixel(x);
  return counts;
}

}  // namespace

ReadResult inspect_gbuffer(const std::string& path, const ReadOptions& options) {
  ReadResult result;
  try {
    Prepared prep;
    if (prepare(path, options, result, prep)) result.gbuffer.camera = prep.camera;
  } catch (const std::exception& e) {
    result.error = path + ": " + e.what();
  } catch (...) {
    result.error = path + ": unknown error while reading the header";
  }
  return result;
}

bool read_scanline_channels(const std::string& path, std::span<const ChannelComponent> channels,
                            cv::Mat& image, int threads) {
  CV_Assert(image.depth() == CV_32F && !image.empty());
  exr_core::Context core;
  if (!open_core(path, core)) return false;
  exr_attr_box2i_t window;
  if (exr_get_data_window(core.get(), 0, &window) != EXR_ERR_SUCCESS) return false;
  const PixelBox data{window.min.x, window.min.y, window.max.x, window.max.y};
  if (data.width() != image.cols || data.height() != image.rows) return false;
  std::vector<ChannelTarget> targets;
  for (const ChannelComponent& c : channels) {
    CV_Assert(c.component >= 0 && c.component < image.channels());
    targets.push_back({c.channel, image.ptr<float>() + c.component, size_t(image.channels()), image.step[0]});
  }
  const std::optional<ZipPlan> plan = plan_zip_part(core.get(), 0, data, targets);
  if (!plan) return false;
  read_zip_part(core.get(), 0, "", false, data, *plan, threads);
  return true;
}

ReadResult read_gbuffer(const std::string& path, const ReadOptions& options) {
  ReadResult result;
  try {
    Prepared prep;
    if (!prepare(path, options, result, prep)) return result;
    FrameInfo& info = result.info;
    GBuffer& g = result.gbuffer;
    g.camera = prep.camera;
    const Camera& camera = prep.camera;
    const cv::Size size(int(prep.data.width()), int(prep.data.height()));
    const bool lighting_from_passes =
        !prep.channels.find("lighting") && prep.channels.find("albedo") &&
        prep.channels.find("diffdir");
    Images img;
    try {
      read_pixels(prep, options, lighting_from_passes, img, size);
    } catch (const std::exception& e) {
      result.error = path + ": cannot read pixels (" + read_failure(e) + "): " + e.what();
      return result;
    }

    const ResolvedInput* normal_in = prep.channels.find("normal");
    const ResolvedInput* position_in = prep.channels.find("position");
    const bool normals_world = normal_in && normal_in->space == Space::world;
    const bool positions_world = position_in && position_in->space == Space::world;
    // Normals transform with the inverse transpose (equal to the rotation for a rigid
    // world_to_view, right for any affine one); they are renormalised afterwards.
    const glm::mat3 normal_to_view = glm::transpose(glm::inverse(glm::mat3(camera.world_to_view)));
    const bool has_normals = !img.normal.empty();

    g.depth_view = img.depth;
    g.mask.create(size, CV_8UC1);
    cv::Mat repair;  // foreground pixels whose stored normal is (0, 0, 0)
    if (has_normals) repair = cv::Mat::zeros(size, CV_8UC1);
    std::vector<int64_t> fg_rows(size.height, 0), nonfinite_rows(size.height, 0),
        repair_rows(size.height, 0);
    std::vector<float> min_rows(size.height, std::numeric_limits<float>::infinity()),
        max_rows(size.height, -std::numeric_limits<float>::infinity());
    const float far_view = camera.far_view;
    const std::optional<float> background = prep.background_depth;
    const bool radial = prep.radial_depth;
    // The view-space point at planar depth 1 is affine in the pixel coordinates for every
    // projection whose clip.w does not depend on x and y (see Camera::view_from_pixel_depth),
    // so rays are stepped across the image instead of solved per pixel.
    const bool perspective = camera.is_perspective();
    const glm::vec3 ray_origin = camera.view_from_pixel_depth({0.5f, 0.5f}, 1.0f);
    const glm::vec3 ray_step_x = camera.view_from_pixel_depth({1.5f, 0.5f}, 1.0f) - ray_origin;
    const glm::vec3 ray_step_y = camera.view_from_pixel_depth({0.5f, 1.5f}, 1.0f) - ray_origin;

    ForegroundPass pass;
    pass.width = size.width;
    pass.far_view = far_view;
    pass.has_background = background.has_value();
    pass.background = background.value_or(0.0f);
    pass.radial = radial;
    pass.perspective = perspective;
    pass.normals_world = normals_world;
    pass.normal_to_view = normal_to_view;
    pass.ray_step_x = ray_step_x;
    parallel_rows(cv::Range(0, size.height), options.threads, [&](const cv::Range& rows) {
      for (int y = rows.start; y < rows.end; ++y) {
        const RowCounts counts = foreground_row(
            pass, ray_origin + float(y) * ray_step_y, g.depth_view.ptr<float>(y), g.mask.ptr<uint8_t>(y),
            has_normals ? img.normal.ptr<cv::Vec3f>(y) : nullptr,
            has_normals ? repair.ptr<uint8_t>(y) : nullptr);
        fg_rows[y] = counts.foreground;
        nonfinite_rows[y] = counts.nonfinite;
        repair_rows[y] = counts.repaired;
        min_rows[y] = counts.depth_min;
        max_rows[y] = counts.depth_max;
      }
    });

    for (int y = 0; y < size.height; ++y) {
      info.foreground_pixels += fg_rows[y];
      info.nonfinite_pixels += nonfinite_rows[y];
      info.repaired_normal_pixels += repair_rows[y];
      if (fg_rows[y]) {
        info.depth_min_view = info.foreground_pixels == fg_rows[y]
                                  ? min_rows[y]
                                  : std::min(info.depth_min_view, min_rows[y]);
        info.depth_max_view = std::max(info.depth_max_view, max_rows[y]);
      }
    }
    info.masked_pixels = int64_t(size.area()) - info.foreground_pixels;

    if (has_normals) {
      g.normal_view = img.normal;
      if (info.repaired_normal_pixels > 0) {
        cv::Mat rebuilt;
        reconstruct_normals_from_depth(g.depth_view, g.mask, camera, rebuilt, {},
                                       options.threads);
        rebuilt.copyTo(g.normal_view, repair);
        info.notes.push_back(std::to_string(info.repaired_normal_pixels) +
                             " foreground pixels had a zero normal: reconstructed from depth");
      }
    } else {
      reconstruct_normals_from_depth(g.depth_view, g.mask, camera, g.normal_view, {},
                                     options.threads);
      info.normals_reconstructed = true;
    }

    if (options.read_positions) {
      if (!img.position.empty()) {
        g.position_view = img.position;
        parallel_rows(cv::Range(0, size.height), options.threads, [&](const cv::Range& rows) {
          for (int y = rows.start; y < rows.end; ++y) {
            cv::Vec3f* p = g.position_view.ptr<cv::Vec3f>(y);
            const uint8_t* m = g.mask.ptr<uint8_t>(y);
            for (int x = 0; x < size.width; ++x) {
              if (!m[x] || !std::isfinite(p[x][0] + p[x][1] + p[x][2])) {
                p[x] = cv::Vec3f(0, 0, 0);
                continue;
              }
              if (positions_world) {
                const glm::vec3 v = camera.view_from_world_point({p[x][0], p[x][1], p[x][2]});
                p[x] = cv::Vec3f(v.x, v.y, v.z);
              }
            }
          }
        });
      } else {
        view_positions_from_depth(g.depth_view, g.mask, camera, g.position_view, {},
                                  options.threads);
        info.uses.push_back({"position", "computed from depth", "view"});
      }
    }

    // Kernels multiply with albedo and lighting: non-finite values become 0 (the
    // reference passes are left as the renderer wrote them).
    set_nonfinite_to_zero(img.albedo);
    if (options.read_lighting) {
      if (!img.lighting.empty()) {
        g.lighting = img.lighting;
      } else if (!img.albedo.empty() && !img.diffdir.empty()) {
        // Sender radiance of a Lambertian pixel under the renderer's direct light:
        // albedo x direct irradiance-like pass (Cycles: DiffCol * DiffDir, see README),
        // in the pass's own image unless a reference pass shares it.
        bool shared = false;
        for (const auto& [name, m] : img.references) shared = shared || m.data == img.diffdir.data;
        if (shared) {
          g.lighting = img.albedo.mul(img.diffdir);
        } else {
          cv::multiply(img.diffdir, img.albedo, img.diffdir);
          g.lighting = img.diffdir;
        }
      }
      set_nonfinite_to_zero(g.lighting);
    }
    if (options.read_albedo) g.albedo = img.albedo;
    if (options.read_references) {
      for (auto& [name, m] : img.references) g.references[name] = m;
    }
    return result;
  } catch (const std::exception& e) {
    result.error = path + ": " + e.what();
  } catch (...) {
    result.error = path + ": unknown error while reading";
  }
  result.gbuffer = GBuffer{};
  return result;
}

}  // namespace ssdo
