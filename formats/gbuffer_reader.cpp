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
#include <mutex>
#include <new>
#include <sstream>
#include <stdexcept>

#include <Imath/half.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDeepFrameBuffer.h>
#include <OpenEXR/ImfDeepScanLineInputPart.h>
#include <OpenEXR/ImfDeepTiledInputPart.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/openexr.h>

#include "formats/camera_io.h"
#include "formats/channel_profiles.h"
#include "formats/exr_core.h"
#include "formats/exr_header_check.h"
#include "core/half_samples.h"
#include "formats/exr_zip.h"
#include "formats/foreground_pass.h"
#include "formats/input_file.h"
#include "core/parallel.h"

namespace ssdo {

namespace {

using foreground::ForegroundPass;
using foreground::RowCounts;
using foreground::eye_ray;
using foreground::foreground_row;
using foreground::planar_depth;
using foreground::row_ray;

// A resource limit of ReadOptions refused the read (not a damaged file).
struct LimitExceeded : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// What a failed read is called, and whether it ran out of a resource (the reader's chunk
// decoder rethrows an allocation failure as std::bad_alloc).
const char* read_failure(const std::exception& e, ResourceFailure& exhausted) {
  exhausted = resource_failure(e);
  if (dynamic_cast<const LimitExceeded*>(&e)) return "over the resource limits";
  if (exhausted == ResourceFailure::memory) return "out of memory";
  if (exhausted == ResourceFailure::thread) return "no thread could start";
  return "damaged or truncated file";
}

// An exception outside the decoding: its text, and whether it ran out of a resource.
void fail_with(ReadResult& result, const std::string& path, const std::exception& e) {
  result.error = path + ": " + e.what();
  result.exhausted = resource_failure(e);
}

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
  // Lighting is albedo x the direct light pass (no lighting channel of its own).
  bool lighting_from_passes = false;
  Camera camera;
  bool camera_has_world = false;  // sidecar or header: world_to_view is meaningful
  bool radial_depth = false;
  bool depth_kind_stated = false;  // by the sidecar
  std::optional<float> background_depth;
  std::optional<std::string> sidecar_normal_space, sidecar_position_space;
  // The normals' space was stated by nothing (profile, mapping or sidecar) and the camera
  // has no world transform: they are taken as view space, to be checked against the data.
  bool normal_space_assumed = false;
  // The back-face depth is the deep depth part's next surface (no back channel mapped).
  bool deep_back = false;
};

bool fail(ReadResult& result, std::string message) {
  result.error = std::move(message);
  return false;
}

// " (part "NAME")" in a multi-part file, else "".
std::string part_label(const Prepared& prep, int part) {
  return prep.parts.size() > 1 ? " (part \"" + prep.parts[part].name + "\")" : "";
}

// Which resolved inputs the options ask to read.
bool wanted(const ResolvedInput& r, const ReadOptions& o, bool lighting_from_passes) {
  if (r.input == "depth") return true;
  if (r.input == "normal") return o.read_normals;
  if (r.input == "depth_back") return o.read_depth_back;
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

// The file's headers against the limits (formats/exr_header_check.h), before OpenEXR
// allocates from them; then OpenEXR's reader and every part's name and channels.
bool open_file(const std::string& path, const ReadOptions& options, ReadResult& result,
               Prepared& prep) {
  result.info.path = path;
  prep.path = path;
  if (std::string e = input_file_error(path, ""); !e.empty()) return fail(result, e);
  const ExrHeaderCheck check =
      check_exr_headers(path, {options.max_pixels, options.max_decoded_bytes});
  if (!check.ok()) return fail(result, check.error);
  const int threads = options.threads > 0 ? options.threads : Imf::globalThreadCount();
  // OpenEXR decodes on its process-wide pool; asking for N threads makes sure it has N.
  if (options.threads > 1 && Imf::globalThreadCount() < options.threads)
    Imf::setGlobalThreadCount(options.threads);
  try {
    prep.file = std::make_unique<Imf::MultiPartInputFile>(path.c_str(), threads);
  } catch (const std::exception& e) {
    const char* what = read_failure(e, result.exhausted);
    return fail(result, path + ": cannot read the EXR header (" + what + "): " + e.what());
  }
  for (int i = 0; i < prep.file->parts(); ++i) {
    const Imf::Header& h = prep.file->header(i);
    PartChannels pc;
    pc.name = h.hasName() ? h.name() : std::string();
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
      pc.channels.push_back(it.name());
    result.info.parts.push_back(pc.name);
    prep.parts.push_back(std::move(pc));
  }
  return true;
}

// The channels to read (formats/channel_profiles.h) and the pixel grid, the depth part's
// data window: absurd sizes are refused before anything is allocated.
bool resolve_grid(const std::string& path, const ReadOptions& options, ReadResult& result,
                  Prepared& prep) {
  FrameInfo& info = result.info;
  std::string error;
  auto resolved = resolve_channels(path, prep.parts, options, &error);
  if (!resolved) return fail(result, error);
  prep.channels = *resolved;
  const int part = prep.channels.part;
  const Imf::Header& header = prep.file->header(part);
  info.part = prep.parts[part].name;
  info.profile = prep.channels.profile;
  info.layer = prep.channels.layer;
  if (const std::vector<std::string>& layers = prep.channels.layers; layers.size() > 1) {
    std::string others;
    for (const std::string& l : layers)
      if (l != info.layer) others += (others.empty() ? "" : ", ") + l;
    const std::string& mapped = options.mapping.depth;
    const bool chosen = mapped == info.layer + ".Depth.Z" || mapped == info.layer + ".Depth";
    info.notes.push_back(!chosen
                             ? std::string(kWarningNote) + "view layers " + info.layer + ", " + others +
                                   ": the inputs are " + info.layer + "'s; --map depth=" + layers.back() +
                                   ".Depth.Z reads another's"
                             : "view layer " + info.layer + " (the mapped depth's; also in the file: " + others +
                                   "): the inputs the mapping does not name are its own");
  }
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
  if (prep.data.width() <= 0 || prep.data.height() <= 0 || prep.data.width() > INT_MAX / 16 ||
      prep.data.height() > INT_MAX / 16 ||
      prep.data.width() * prep.data.height() > options.max_pixels)
    return fail(result, path + part_label(prep, part) + ": data window " +
                            describe_box(prep.data) + " refused (limit " +
                            std::to_string(options.max_pixels) + " pixels)");
  prep.lighting_from_passes = !prep.channels.find("lighting") && prep.channels.find("albedo") &&
                              prep.channels.find("diffdir");
  return true;
}

bool is_deep(const Imf::Header& h) {
  return h.type() == Imf::DEEPSCANLINE || h.type() == Imf::DEEPTILE;
}

// A deep depth part gives the back-face depth from its samples, unless a channel is mapped
// to it: a back channel the profile found in the deep part itself is that part's nearest
// sample of it, not a second surface.
void choose_back_layer(const ReadOptions& options, Prepared& prep) {
  if (!is_deep(prep.file->header(prep.channels.part)) || !options.mapping.depth_back.empty())
    return;
  std::erase_if(prep.channels.inputs,
                [](const ResolvedInput& r) { return r.input == "depth_back"; });
  prep.deep_back = options.read_depth_back;
}

// The channel --map names for `input` ("normal", "reference:AO"); empty when a profile
// found it.
const std::string& mapped_channel(const std::string& input, const ChannelMapping& m) {
  static const std::string none;
  if (input == "depth") return m.depth;
  if (input == "depth_back") return m.depth_back;
  if (input == "normal") return m.normal;
  if (input == "position") return m.position;
  if (input == "albedo") return m.albedo;
  if (input == "lighting") return m.lighting;
  if (input.rfind("reference:", 0) == 0)
    if (const auto it = m.references.find(input.substr(10)); it != m.references.end()) return it->second;
  return none;
}

// Every part a used channel comes from must share the depth part's pixel grid, with
// full-resolution channels (flat or deep).
bool check_used_parts(const std::string& path, const ReadOptions& options, ReadResult& result,
                      Prepared& prep) {
  const int part = prep.channels.part;
  // An input a profile found (not --map) in a part of another size is left out with a note,
  // as a frame without it is read (normals reconstructed from depth, no albedo, ...); so is
  // a reference pass, which the frame's terms do not need.
  std::erase_if(prep.channels.inputs, [&](const ResolvedInput& r) {
    if (r.input == "depth" || !wanted(r, options, prep.lighting_from_passes)) return false;
    if (r.input.rfind("reference:", 0) != 0 && !mapped_channel(r.input, options.mapping).empty()) return false;
    const PixelBox box = box_of(prep.file->header(r.part).dataWindow());
    if (box == prep.data) return false;
    result.info.notes.push_back(r.input + " left out: its part \"" + prep.parts[r.part].name + "\" has data window " +
                                describe_box(box) + ", depth's part \"" + prep.parts[part].name + "\" has " +
                                describe_box(prep.data));
    return true;
  });
  prep.lighting_from_passes =
      prep.lighting_from_passes && prep.channels.find("albedo") && prep.channels.find("diffdir");
  for (const auto& r : prep.channels.inputs) {
    if (!wanted(r, options, prep.lighting_from_passes)) continue;
    const Imf::Header& h = prep.file->header(r.part);
    if (box_of(h.dataWindow()) != prep.data)
      return fail(result, path + ": parts of different sizes: " + r.input + " channels in part \"" +
                              prep.parts[r.part].name + "\" have data window " +
                              describe_box(box_of(h.dataWindow())) + ", depth in part \"" +
                              prep.parts[part].name + "\" has " + describe_box(prep.data));
    for (const auto& c : r.channels) {
      const Imf::Channel* ch = h.channels().findChannel(c);
      if (ch && (ch->xSampling != 1 || ch->ySampling != 1))
        return fail(result, path + part_label(prep, part) + ": channel " + c + " is subsampled (" +
                                std::to_string(ch->xSampling) + "x" +
                                std::to_string(ch->ySampling) +
                                "), which a G-buffer cannot use");
    }
  }
  return true;
}

// The camera of a JSON sidecar, re-targeted from the display window to the data window (a
// sidecar of the data window's size is taken as it is).
bool camera_from_sidecar(const std::string& path, const std::string& sidecar,
                         const ReadOptions& options, ReadResult& result, Prepared& prep) {
  FrameInfo& info = result.info;
  std::string error;
  const std::optional<SidecarCamera> side = read_camera_sidecar(sidecar, &error);
  if (!side) return fail(result, path + ": " + error);
  if (side->width_px == prep.display.width() && side->height_px == prep.display.height()) {
    prep.camera = side->camera;
    prep.camera.view_to_clip =
        projection_for_data_window(side->camera.view_to_clip, prep.display, prep.data);
  } else if (side->width_px == prep.data.width() && side->height_px == prep.data.height()) {
    prep.camera = side->camera;
    info.notes.push_back("sidecar size matches the data window, not the display window");
  } else {
    return fail(result, path + ": camera sidecar " + sidecar + " is for " +
                            std::to_string(side->width_px) + "x" +
                            std::to_string(side->height_px) +
                            " pixels, but the frame's display window is " +
                            describe_box(prep.display) + " and its data window " +
                            describe_box(prep.data));
  }
  prep.camera.width_px = int(prep.data.width());
  prep.camera.height_px = int(prep.data.height());
  prep.camera_has_world = true;
  info.camera_source = "sidecar " + sidecar;
  info.ao_distance_world = side->ao_distance_world;
  prep.background_depth = side->background_depth;
  prep.sidecar_normal_space = side->normal_space;
  prep.sidecar_position_space = side->position_space;
  prep.depth_kind_stated = side->depth_kind.has_value();
  if (options.depth_kind == DepthKind::automatic && side->depth_kind)
    prep.radial_depth = *side->depth_kind == "radial";
  return true;
}

// A 4x4 matrix attribute of a header in glm's column-vector form, stored as M44f (the type
// OpenEXR's standard attributes have) or M44d (as some writers store worldToCamera and
// worldToNDC; OpenEXR's hasWorldToCamera sees only M44f); nullopt when absent or of another
// type. Imath stores x[row][col] in the row-vector convention, so the same 16 values in
// memory order are the column-vector form (formats/camera_io.h, ExrCameraMatrices).
std::optional<glm::mat4> header_matrix(const Imf::Header& h, const char* name) {
  glm::mat4 m;
  if (const auto* a = h.findTypedAttribute<Imf::M44fAttribute>(name)) {
    std::copy(&a->value().x[0][0], &a->value().x[0][0] + 16, &m[0][0]);
    return m;
  }
  if (const auto* a = h.findTypedAttribute<Imf::M44dAttribute>(name)) {
    std::transform(&a->value().x[0][0], &a->value().x[0][0] + 16, &m[0][0], [](double v) { return float(v); });
    return m;
  }
  return std::nullopt;
}

// The part whose header holds worldToCamera and worldToNDC: the depth part first, then the
// others in order; -1 when none does. `partial` then says what the headers hold of the pair
// when they hold one of its attributes (the first such part's), else stays empty.
int header_camera_part(const Prepared& prep, std::string* partial) {
  const int depth_part = prep.channels.part;
  std::vector<int> order{depth_part};
  for (int i = 0; i < prep.file->parts(); ++i)
    if (i != depth_part) order.push_back(i);
  for (int i : order) {
    const Imf::Header& h = prep.file->header(i);
    const bool pose = header_matrix(h, "worldToCamera").has_value();
    const bool projection = header_matrix(h, "worldToNDC").has_value();
    if (pose && projection) return i;
    if (partial->empty() && (pose || projection))
      *partial = std::string("the header") + part_label(prep, i) + " has " +
                 (pose ? "worldToCamera (the pose) but no worldToNDC (the projection)"
                       : "worldToNDC (the projection) but no worldToCamera (the pose)");
  }
  return -1;
}

bool camera_from_fov(const std::string& path, const std::string& sidecar, const std::string& partial_header,
                     const ReadOptions& options, ReadResult& result, Prepared& prep);

// The camera of the OpenEXR header attributes worldToCamera + worldToNDC of `part` (and the
// optional clipNear / clipFar), either camera convention (formats/camera_io.h). Matrices
// that describe no camera are an error, or with --fov a warning and the --fov camera.
bool camera_from_header(const std::string& path, const std::string& sidecar, int part, const ReadOptions& options,
                        ReadResult& result, Prepared& prep) {
  const Imf::Header& h = prep.file->header(part);
  ExrCameraMatrices m;
  m.world_to_camera = *header_matrix(h, "worldToCamera");
  m.world_to_ndc = *header_matrix(h, "worldToNDC");
  // A clip distance as float (OpenEXR's convention), double or int (as some tools write a
  // whole number, e.g. oiiotool's --attrib clipFar 1000); 0 when absent.
  auto clip_distance = [&](const char* name) -> float {
    if (auto* a = h.findTypedAttribute<Imf::FloatAttribute>(name)) return a->value();
    if (auto* a = h.findTypedAttribute<Imf::DoubleAttribute>(name)) return float(a->value());
    if (auto* a = h.findTypedAttribute<Imf::IntAttribute>(name)) return float(a->value());
    return 0.0f;
  };
  const float near_view = clip_distance(kClipNearAttribute), far_view = clip_distance(kClipFarAttribute);
  std::string error, note;
  // The matrices refer to this part's display window; the grid is the depth part's.
  auto cam = camera_from_exr_matrices(m, box_of(h.displayWindow()), prep.data, near_view,
                                      far_view, &error, &note);
  if (!cam) {
    const std::string refused = path + part_label(prep, part) + ": " + error;
    if (!options.fov_x_deg)
      return fail(result, refused + "; a camera sidecar (" + sidecar + ") or --fov DEGREES reads the frame");
    result.info.notes.push_back(std::string(kWarningNote) + refused + "; --fov gives the camera instead");
    return camera_from_fov(path, sidecar, "", options, result, prep);
  }
  prep.camera = *cam;
  prep.camera_has_world = true;
  result.info.camera_source = "header worldToCamera/worldToNDC";
  if (prep.parts.size() > 1) result.info.camera_source += " (part \"" + prep.parts[part].name + "\")";
  result.info.notes.push_back(note);
  return true;
}

// A camera from the caller's horizontal field of view, which spans the display window (the
// full image), like a sidecar's.
// `partial_header` says which half of the header camera the file holds, if one.
bool camera_from_fov(const std::string& path, const std::string& sidecar, const std::string& partial_header,
                     const ReadOptions& options, ReadResult& result, Prepared& prep) {
  if (!options.fov_x_deg && !partial_header.empty())
    return fail(result, path + ": no camera: " + partial_header +
                            ": store the missing attribute, give a JSON sidecar (" + sidecar +
                            " or an explicit camera JSON path), or pass a horizontal field of view (--fov DEGREES)");
  if (!options.fov_x_deg)
    return fail(result, path + ": no camera: give a JSON sidecar (" + sidecar +
                            " or an explicit camera JSON path), store worldToCamera and "
                            "worldToNDC attributes in the EXR header, or pass a horizontal "
                            "field of view (--fov DEGREES)");
  if (!partial_header.empty())
    result.info.notes.push_back(partial_header + ": it is not used; --fov gives the camera");
  const float fov = *options.fov_x_deg;
  if (!(fov > 0.0f && fov < 180.0f))
    return fail(result, path + ": field of view " + std::to_string(fov) +
                            " degrees is outside (0, 180)");
  // Pixels wider than tall (anamorphic plates) narrow the vertical field of view.
  const float pixel_aspect = prep.file->header(prep.channels.part).pixelAspectRatio();
  const bool square = !(std::isfinite(pixel_aspect) && pixel_aspect > 0.0f) || pixel_aspect == 1.0f;
  Camera cam = Camera::from_fov_x(int(prep.display.width()), int(prep.display.height()), fov, 0.05f, 1000.0f,
                                  square ? 1.0f : pixel_aspect);
  if (!square) {
    std::ostringstream note;
    note << "pixels " << pixel_aspect
         << " times as wide as tall (pixelAspectRatio): the vertical field of view follows";
    result.info.notes.push_back(note.str());
  }
  cam.view_to_clip = projection_for_data_window(cam.view_to_clip, prep.display, prep.data);
  cam.width_px = int(prep.data.width());
  cam.height_px = int(prep.data.height());
  cam.near_view = cam.far_view = 0.0f;  // defaults of from_fov_x, not known clips
  prep.camera = cam;
  std::ostringstream source;
  source << "--fov " << fov;
  result.info.camera_source = source.str();
  if (prep.display != prep.data)
    result.info.notes.push_back(
        "field of view spans the display window; the data window sees a part of it");
  return true;
}

// Camera: sidecar, then header matrices, then --fov; then the depth kind (the options',
// else the sidecar's, else planar).
bool resolve_camera(const std::string& path, const ReadOptions& options, ReadResult& result,
                    Prepared& prep) {
  FrameInfo& info = result.info;
  const std::string sidecar =
      options.camera_json.empty() ? sidecar_path_for(path) : options.camera_json;
  std::error_code ec;
  bool ok = false;
  std::string partial_header;
  if (!options.camera_json.empty() || std::filesystem::exists(sidecar, ec))
    ok = camera_from_sidecar(path, sidecar, options, result, prep);
  else if (const int part = header_camera_part(prep, &partial_header); part >= 0)
    ok = camera_from_header(path, sidecar, part, options, result, prep);
  else
    ok = camera_from_fov(path, sidecar, partial_header, options, result, prep);
  if (!ok) return false;
  if (options.fov_x_deg && prep.camera_has_world)
    info.notes.push_back("the given field of view is ignored: the frame's camera (" +
                         info.camera_source + ") takes precedence");
  if (options.depth_kind != DepthKind::automatic)
    prep.radial_depth = options.depth_kind == DepthKind::radial;
  else if (!prep.depth_kind_stated)
    info.notes.push_back("depth kind not stated by the file or sidecar: planar assumed");
  info.depth_kind = prep.radial_depth ? "radial" : "planar";
  if (prep.camera.is_perspective()) {
    info.fov_x_deg = prep.camera.fov_x_deg();
    info.fov_y_deg = prep.camera.fov_y_deg();
  } else {  // NDC x = p00 x + p30 spans 2 over the data window
    info.view_width = 2.0f / std::abs(prep.camera.view_to_clip[0][0]);
    info.view_height = 2.0f / std::abs(prep.camera.view_to_clip[1][1]);
  }
  info.near_view = prep.camera.near_view;
  info.far_view = prep.camera.far_view;
  return true;
}

// What became what: the space of normals and positions, and each used input's channels.
void report_uses(const ReadOptions& options, Prepared& prep, FrameInfo& info) {
  for (auto& r : prep.channels.inputs) {
    if (r.input == "normal") {
      prep.normal_space_assumed =
          r.space == Space::automatic && !prep.sidecar_normal_space && !prep.camera_has_world;
      r.space = decide_space(r.space, prep.sidecar_normal_space, prep.camera_has_world);
    }
    if (r.input == "position")
      r.space = decide_space(r.space, prep.sidecar_position_space, prep.camera_has_world);
  }
  // A positions pass is read only when asked for (ReadOptions::read_positions): otherwise
  // the terms take view-space positions from depth and the camera, and the channel is
  // said to be unused rather than listed nowhere.
  std::erase_if(prep.channels.inputs, [&](const ResolvedInput& r) {
    if (r.input != "position" || options.read_positions) return false;
    info.notes.push_back("position channels " + r.describe() +
                         " are not used: view-space positions come from depth and the camera");
    return true;
  });
  // World-space normals or positions under a camera without a pose (a bare --fov) cannot be
  // brought into view space: they are not read (the normals are rebuilt from depth, the
  // positions computed from it), rather than taken as view space.
  if (!prep.camera_has_world)
    std::erase_if(prep.channels.inputs, [&](const ResolvedInput& r) {
      const bool world = (r.input == "normal" || r.input == "position") && r.space == Space::world;
      if (world)
        info.notes.push_back(r.input + " channels " + r.describe() +
                             " are world space and the camera (--fov) has no pose to rotate them: " +
                             (r.input == "normal" ? "normals rebuilt from depth" : "positions computed from depth"));
      return world;
    });
  for (const auto& r : prep.channels.inputs) {
    if (!wanted(r, options, prep.lighting_from_passes) || r.input == "diffdir") continue;
    if (r.input == "albedo" && !options.read_albedo) continue;
    std::string channels = r.describe();
    if (prep.parts.size() > 1) channels = prep.parts[r.part].name + ":" + channels;
    info.uses.push_back({r.input, channels, space_name(r.space)});
  }
  if (options.read_lighting && prep.lighting_from_passes)
    info.uses.push_back({"lighting",
                         prep.channels.find("albedo")->describe() + " * " +
                             prep.channels.find("diffdir")->describe() +
                             " (albedo x direct irradiance = sender radiance)",
                         ""});
  if (!prep.channels.find("normal")) info.normals_reconstructed = true;
  const ResolvedInput& depth = *prep.channels.find("depth");
  if (prep.deep_back) {
    info.back_layer = "deep samples of " + depth.channels[0];
    info.uses.push_back(
        {"depth_back", depth.channels[0] + " (deep: the next surface behind the nearest sample)", ""});
    return;
  }
  const ResolvedInput* back = prep.channels.find("depth_back");
  if (back && options.read_depth_back) info.back_layer = "channel " + back->describe();
}

bool prepare(const std::string& path, const ReadOptions& options, ReadResult& result,
             Prepared& prep) {
  if (!open_file(path, options, result, prep) || !resolve_grid(path, options, result, prep) ||
      !check_used_parts(path, options, result, prep))
    return false;
  choose_back_layer(options, prep);
  if (!resolve_camera(path, options, result, prep)) return false;
  report_uses(options, prep, result.info);
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
// Imath converts it (core/half_samples.h), float as is.
void convert_samples(const uint8_t* from, exr_pixel_type_t type, int64_t width, float* to,
                     size_t pixel_floats) {
  if (type == EXR_PIXEL_HALF) {
    half_samples::to_float(from, width, to, pixel_floats);
  } else {
    for (int64_t x = 0; x < width; ++x)
      std::memcpy(&to[size_t(x) * pixel_floats], from + 4 * x, 4);
  }
}

// Where the chunk of the lines [y, y + lines) of a part is, how big it is, and why it is
// refused ("" when it is not).
std::string locate_chunk(exr_const_context_t context, int part, int y, int lines, int64_t width,
                         const ZipPlan& plan, exr_chunk_info_t& info) {
  info = exr_chunk_info_t{};
  exr_core::forget_error();
  if (const exr_result_t rv = exr_read_scanline_chunk_info(context, part, y, &info);
      rv != EXR_ERR_SUCCESS)
    return "cannot locate the chunk (" + exr_core::error_text(rv) + ")";
  const uint64_t expected = uint64_t(lines) * plan.line_bytes;
  // Core derives these from the header; checked all the same, since the conversion writes
  // exactly `lines` rows of the images from exactly `expected` bytes.
  if (info.start_y != y || info.height != lines || info.width != width ||
      info.compression != uint8_t(plan.compression) || info.unpacked_size != expected)
    return "chunk layout disagrees with the header (" + std::to_string(info.height) +
           " lines from " + std::to_string(info.start_y) + ", " +
           std::to_string(info.unpacked_size) + " bytes; expected " + std::to_string(lines) +
           " lines from " + std::to_string(y) + ", " + std::to_string(expected) + " bytes)";
  // A stored chunk is never larger than its pixels: the format stores the pixels as they
  // are when compression does not make them smaller, and uncompressed parts always.
  if (info.packed_size > expected ||
      (plan.compression == EXR_COMPRESSION_NONE && info.packed_size != expected) ||
      (info.packed_size == 0 && expected > 0))
    return "chunk of " + std::to_string(info.packed_size) + " bytes for " +
           std::to_string(expected) + " bytes of pixels";
  return "";
}

// Converts `lines` packed lines, the first being row `row` of the data window, into every
// target image.
void unpack_lines(const uint8_t* pixels, size_t row, int lines, int64_t width, const ZipPlan& plan) {
  for (int line = 0; line < lines; ++line, ++row) {
    const uint8_t* from = pixels + size_t(line) * plan.line_bytes;
    for (const ZipChannel& c : plan.channels) {
      const ChannelTarget& t = *c.target;
      float* to = reinterpret_cast<float*>(reinterpret_cast<uint8_t*>(t.first) + row * t.row_bytes);
      convert_samples(from + c.line_offset_bytes, c.type, width, to, t.pixel_floats);
    }
  }
}

// Reads, inflates and converts one chunk into the images; "" on success, else what is wrong
// with it. `stored` and `packed` are the calling thread's buffers (their contents are
// overwritten).
std::string decode_chunk(exr_const_context_t context, int part, const PixelBox& data,
                         const ZipPlan& plan, int chunk, std::vector<uint8_t>& stored,
                         std::vector<uint8_t>& packed) {
  const int y = int(data.min_y + int64_t(chunk) * plan.lines_per_chunk);
  const int lines = int(std::min<int64_t>(plan.lines_per_chunk, data.max_y - y + 1));
  exr_chunk_info_t info;
  if (std::string refused = locate_chunk(context, part, y, lines, data.width(), plan, info);
      !refused.empty())
    return refused;
  const uint64_t expected = uint64_t(lines) * plan.line_bytes;
  // Core checked packed_size against the file's size: this allocation is bounded by it.
  stored.resize(size_t(info.packed_size));
  exr_core::forget_error();
  if (const exr_result_t rv = exr_read_chunk(context, part, &info, stored.data());
      rv != EXR_ERR_SUCCESS)
    return "cannot read the chunk (" + exr_core::error_text(rv) + ")";
  const uint8_t* pixels = stored.data();
  if (info.packed_size < expected) {
    packed.resize(size_t(expected));
    if (!exr_zip::decompress(stored, packed))
      return "ZIP data of " + std::to_string(info.packed_size) +
             " bytes does not inflate to the chunk's " + std::to_string(expected) + " bytes";
    pixels = packed.data();
  }
  unpack_lines(pixels, size_t(y - data.min_y), lines, data.width(), plan);
  return "";
}

// A chunk's bytes as stored and as inflated.
struct ChunkBuffers {
  std::vector<uint8_t> stored, packed;
};

// Reads, inflates and converts every chunk of the part; throws on the first damaged chunk
// (the lowest scanline, whatever the thread count), naming the part and the scanline.
void read_zip_part(exr_const_context_t context, int part, const std::string& part_name,
                   bool multi_part, const PixelBox& data, const ZipPlan& plan, int threads) {
  std::vector<std::string> errors(size_t(plan.chunks));
  std::atomic<int> first_failed{plan.chunks};
  std::atomic<bool> out_of_memory{false};
  auto fail = [&](int chunk, std::string message) {
    errors[size_t(chunk)] = std::move(message);
    int seen = first_failed.load();
    while (chunk < seen && !first_failed.compare_exchange_weak(seen, chunk)) {
    }
  };
  // A strip is one chunk, and buffers of its own would allocate and zero a chunk's bytes
  // (2 MB for 16 lines of a 1080p G-buffer) per chunk: a strip takes a pair of buffers the
  // strips before it returned (one pair per thread in flight; they grow, and are zeroed,
  // only for a chunk larger than any before), and the part's read frees them.
  std::mutex buffers_mutex;
  std::vector<ChunkBuffers> free_buffers;
  // One strip per chunk (16 or 1 lines): the chunks are the unit of work.
  parallel_rows(cv::Range(0, plan.chunks), threads, [&](const cv::Range& range) {
    ChunkBuffers buffers;
    {
      const std::lock_guard lock(buffers_mutex);
      if (!free_buffers.empty()) buffers = std::move(free_buffers.back()), free_buffers.pop_back();
    }
    for (int chunk = range.start; chunk < range.end; ++chunk) {
      // Chunks after a damaged one are not worth reading; those before it still decide which
      // error is reported.
      if (chunk > first_failed.load()) break;
      try {
        std::string error = decode_chunk(context, part, data, plan, chunk, buffers.stored, buffers.packed);
        if (!error.empty()) fail(chunk, std::move(error));
      } catch (const std::bad_alloc&) {
        out_of_memory = true;
        fail(chunk, "out of memory");
      } catch (const std::exception& e) {
        fail(chunk, e.what());
      }
    }
    try {
      const std::lock_guard lock(buffers_mutex);
      free_buffers.push_back(std::move(buffers));
    } catch (const std::bad_alloc&) {  // the buffers are freed here instead
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
  cv::Mat depth, depth_back, normal, position, albedo, diffdir, lighting;
  std::map<std::string, cv::Mat> references;
};

cv::Mat* image_for(const std::string& input, Images& img) {
  if (input == "depth") return &img.depth;
  if (input == "depth_back") return &img.depth_back;
  if (input == "normal") return &img.normal;
  if (input == "position") return &img.position;
  if (input == "albedo") return &img.albedo;
  if (input == "diffdir") return &img.diffdir;
  if (input == "lighting") return &img.lighting;
  return &img.references[input.substr(std::string("reference:").size())];
}

// Where each wanted channel goes: one slice per channel, interleaved by the slice strides,
// per part for OpenEXR (buffers) and for read_zip_part (targets).
struct SlicePlan {
  std::map<int, Imf::FrameBuffer> buffers;
  std::map<int, std::vector<ChannelTarget>> targets;
  std::vector<std::pair<cv::Mat*, cv::Mat*>> aliases;  // (alias, image read)
  struct Copy {
    cv::Mat* from;
    int from_component;
    cv::Mat* to;
    int to_component;
  };
  std::vector<Copy> copies;  // components read once and used twice
};

// Allocates the images of the wanted inputs and plans their slices.
SlicePlan plan_slices(const Prepared& prep, const ReadOptions& options, Images& img) {
  SlicePlan plan;
  const cv::Size size(int(prep.data.width()), int(prep.data.height()));
  std::map<std::string, cv::Mat*> read_into;
  std::map<std::string, std::pair<cv::Mat*, int>> first_use;  // "part:channel" -> image, component
  const Imath::Box2i window(Imath::V2i(prep.data.min_x, prep.data.min_y),
                            Imath::V2i(prep.data.max_x, prep.data.max_y));
  for (const auto& r : prep.channels.inputs) {
    if (!wanted(r, options, prep.lighting_from_passes)) continue;
    cv::Mat* target = image_for(r.input, img);
    // Two inputs on the same channels (DiffDir as lighting factor and as reference) share
    // one image: OpenEXR takes one slice per channel name.
    const std::string key = std::to_string(r.part) + ":" + join_names(r.channels);
    if (auto it = read_into.find(key); it != read_into.end()) {
      plan.aliases.emplace_back(target, it->second);
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
        plan.copies.push_back({it->second.first, it->second.second, target, c});
        continue;
      }
      first_use[channel_key] = {target, c};
      plan.buffers[r.part].insert(r.channels[c],
                                  Imf::Slice::Make(Imf::FLOAT, target->ptr<float>() + c, window,
                                                   sizeof(float) * n, target->step[0]));
      plan.targets[r.part].push_back({r.channels[c], target->ptr<float>() + c, size_t(n),
                                      target->step[0]});
    }
  }
  return plan;
}

// ---------------------------------------------------------------------------------------
// Deep parts (OpenEXR "Interpreting OpenEXR Deep Pixels"): every sample of the wanted
// channels is read, then each pixel is flattened to its nearest sample.

// The channels read from a deep part: the wanted ones (the targets, in their order), then
// the depth ordering the samples and the ZBack ending the nearest one when not among them.
struct DeepChannels {
  std::vector<std::string> names;
  int depth = -1;
  int depth_end = -1;  // ZBack, or -1 when the part has none
};

// Every sample of a part's DeepChannels, as float, pixel after pixel in row order.
struct DeepPixels {
  std::vector<uint32_t> counts;            // samples per pixel of the data window
  std::vector<size_t> first;               // each pixel's first sample; pixels + 1 entries
  std::vector<std::vector<float>> values;  // per channel, every sample
};

DeepChannels deep_channels(const Prepared& prep, int part,
                           const std::vector<ChannelTarget>& targets) {
  const Imf::ChannelList& list = prep.file->header(part).channels();
  DeepChannels ch;
  for (const ChannelTarget& t : targets) ch.names.push_back(t.channel);
  auto index_of = [&](const std::string& name) {
    const auto it = std::find(ch.names.begin(), ch.names.end(), name);
    if (it != ch.names.end()) return int(it - ch.names.begin());
    ch.names.push_back(name);
    return int(ch.names.size()) - 1;
  };
  // The samples are ordered by the frame's depth channel, else by the part's own Z.
  std::string depth = prep.channels.find("depth")->channels[0];
  if (!list.findChannel(depth)) depth = "Z";
  if (!list.findChannel(depth))
    throw std::runtime_error("deep part \"" + prep.parts[part].name +
                             "\" has no depth channel (" + depth + ") to order its samples by");
  ch.depth = index_of(depth);
  if (list.findChannel("ZBack")) ch.depth_end = index_of("ZBack");
  return ch;
}

// Bytes a sample costs: decoding every channel of the part as stored (OpenEXR decodes them
// all) and keeping the read ones as float.
int64_t deep_sample_bytes(const Imf::Header& h, const DeepChannels& ch) {
  int64_t bytes = int64_t(sizeof(float)) * int64_t(ch.names.size());
  for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
    bytes += it.channel().type == Imf::HALF ? 2 : 4;
  return bytes;
}

// After the sample counts are read: refuses more samples than the limits allow, then sizes
// the sample arrays and points each pixel's slice pointers into them.
void allocate_deep_samples(const std::string& part_name, const Imf::Header& h,
                           const DeepChannels& ch, const ReadOptions& options, DeepPixels& px,
                           std::vector<std::vector<float*>>& pointers) {
  px.first.resize(px.counts.size() + 1);
  uint64_t total = 0;
  for (size_t i = 0; i < px.counts.size(); ++i) {
    px.first[i] = size_t(total);
    total += px.counts[i];
  }
  px.first.back() = size_t(total);
  const uint64_t per_sample = uint64_t(deep_sample_bytes(h, ch));
  if (total > uint64_t(options.max_decoded_bytes) / per_sample)
    throw LimitExceeded("deep part" + (part_name.empty() ? "" : " \"" + part_name + "\"") +
                        " holds " + std::to_string(total) +
                        " samples of " + std::to_string(per_sample) + " bytes, over the limit of " +
                        std::to_string(options.max_decoded_bytes) + " decoded bytes");
  px.values.assign(ch.names.size(), std::vector<float>(size_t(total)));
  for (size_t c = 0; c < ch.names.size(); ++c)
    for (size_t i = 0; i < px.counts.size(); ++i)
      pointers[c][i] = px.values[c].data() + px.first[i];
}

// Reads the samples of a deep scanline or deep tiled part (level 0) with OpenEXR.
void read_deep_samples(Prepared& prep, int part, const DeepChannels& ch, const ReadOptions& options,
                       DeepPixels& px) {
  const Imf::Header& h = prep.file->header(part);
  const PixelBox& data = prep.data;
  const size_t width = size_t(data.width()), pixels = width * size_t(data.height());
  const Imath::Box2i window(Imath::V2i(data.min_x, data.min_y), Imath::V2i(data.max_x, data.max_y));
  px.counts.assign(pixels, 0);
  std::vector<std::vector<float*>> pointers(ch.names.size(), std::vector<float*>(pixels, nullptr));
  Imf::DeepFrameBuffer fb;
  fb.insertSampleCountSlice(Imf::Slice::Make(Imf::UINT, px.counts.data(), window, 4, 4 * width));
  for (size_t c = 0; c < ch.names.size(); ++c) {
    // OpenEXR addresses pixel (x, y) at base + x * xStride + y * yStride (as Slice::Make).
    const intptr_t base = reinterpret_cast<intptr_t>(pointers[c].data()) -
                          (intptr_t(data.min_x) + intptr_t(data.min_y) * intptr_t(width)) *
                              intptr_t(sizeof(float*));
    fb.insert(ch.names[c], Imf::DeepSlice(Imf::FLOAT, reinterpret_cast<char*>(base), sizeof(float*),
                                          sizeof(float*) * width, sizeof(float)));
  }
  const std::string& name = prep.parts[part].name;
  if (h.type() == Imf::DEEPSCANLINE) {
    Imf::DeepScanLineInputPart in(*prep.file, part);
    in.setFrameBuffer(fb);
    in.readPixelSampleCounts(data.min_y, data.max_y);
    allocate_deep_samples(name, h, ch, options, px, pointers);
    in.readPixels(data.min_y, data.max_y);
  } else {
    Imf::DeepTiledInputPart in(*prep.file, part);
    in.setFrameBuffer(fb);
    const int tiles_x = in.numXTiles(0), tiles_y = in.numYTiles(0);
    in.readPixelSampleCounts(0, tiles_x - 1, 0, tiles_y - 1);
    allocate_deep_samples(name, h, ch, options, px, pointers);
    in.readTiles(0, tiles_x - 1, 0, tiles_y - 1);
  }
}

// One pixel's samples flattened: the index of the nearest (smallest depth; -1 when none has
// a depth) and the depth of the next surface behind it (+inf when none): the nearest depth
// beyond max(Z, ZBack) of the nearest sample by kDeepSurfaceGapRelative of it.
std::pair<int64_t, float> nearest_and_next(const DeepPixels& px, const DeepChannels& ch,
                                           size_t pixel) {
  const float* z = px.values[size_t(ch.depth)].data() + px.first[pixel];
  const int64_t n = px.counts[pixel];
  int64_t nearest = -1;
  for (int64_t k = 0; k < n; ++k)
    if (!std::isnan(z[k]) && (nearest < 0 || z[k] < z[nearest])) nearest = k;
  float next = std::numeric_limits<float>::infinity();
  if (nearest < 0) return {nearest, next};
  float end = z[nearest];
  if (ch.depth_end >= 0)
    end = std::max(end, px.values[size_t(ch.depth_end)][px.first[pixel] + size_t(nearest)]);
  const float beyond = end + kDeepSurfaceGapRelative * std::abs(end);
  for (int64_t k = 0; k < n; ++k)
    if (z[k] > beyond && z[k] < next) next = z[k];
  return {nearest, next};
}

// Float `x` of row `y` of a target image.
inline float& target_at(const ChannelTarget& t, int y, int64_t x) {
  return reinterpret_cast<float*>(reinterpret_cast<uint8_t*>(t.first) + size_t(y) * t.row_bytes)
      [size_t(x) * t.pixel_floats];
}

// Each pixel's nearest sample into the targets (0 where the pixel has no sample: background;
// NaN where no sample has a depth) and the next surface's depth into `back` when given.
void flatten_deep(const DeepPixels& px, const DeepChannels& ch,
                  const std::vector<ChannelTarget>& targets, const ChannelTarget* back,
                  const PixelBox& data, int threads) {
  const int64_t width = data.width();
  parallel_rows(cv::Range(0, int(data.height())), threads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int64_t x = 0; x < width; ++x) {
        const size_t pixel = size_t(y) * size_t(width) + size_t(x);
        const auto [nearest, next] = nearest_and_next(px, ch, pixel);
        const float none = px.counts[pixel] == 0 ? 0.0f : std::numeric_limits<float>::quiet_NaN();
        for (size_t c = 0; c < targets.size(); ++c)
          target_at(targets[c], y, x) =
              nearest >= 0 ? px.values[c][px.first[pixel] + size_t(nearest)] : none;
        if (back) target_at(*back, y, x) = next;
      }
  });
}

// Reads a deep part into the targets' images, flattened (formats/gbuffer_reader.h, "Deep
// parts"); `back` receives the next surface's depth when given.
void read_deep_part(Prepared& prep, const ReadOptions& options, int part,
                    const std::vector<ChannelTarget>& targets, const ChannelTarget* back) {
  const DeepChannels ch = deep_channels(prep, part, targets);
  DeepPixels px;
  read_deep_samples(prep, part, ch, options, px);
  flatten_deep(px, ch, targets, back, prep.data, options.threads);
}

// Decodes every planned part: ZIP parts with read_zip_part (ZipDecoder::libdeflate), the
// others with OpenEXR, which converts half to float either way.
void decode_parts(Prepared& prep, const ReadOptions& options, SlicePlan& plan,
                  const ChannelTarget* deep_back) {
  exr_core::Context core;
  bool core_tried = false;
  for (auto& [part, fb] : plan.buffers) {
    if (!prep.file->partComplete(part))
      throw std::runtime_error("incomplete or truncated file: part \"" + prep.parts[part].name +
                               "\" is missing pixel data");
    if (is_deep(prep.file->header(part))) {
      read_deep_part(prep, options, part, plan.targets[part],
                     part == prep.channels.part ? deep_back : nullptr);
      continue;
    }
    if (options.zip_decoder == ZipDecoder::libdeflate) {
      if (!core_tried) {
        core_tried = true;
        open_core(prep.path, core);
      }
      if (core.get()) {
        if (auto zip = plan_zip_part(core.get(), part, prep.data, plan.targets[part])) {
          read_zip_part(core.get(), part, prep.parts[part].name, prep.parts.size() > 1,
                        prep.data, *zip, options.threads);
          continue;
        }
      }
    }
    Imf::InputPart in(*prep.file, part);
    in.setFrameBuffer(fb);
    in.readPixels(prep.data.min_y, prep.data.max_y);
  }
}

// Reads the wanted channels of each part straight into the float images.
void read_pixels(Prepared& prep, const ReadOptions& options, Images& img) {
  SlicePlan plan = plan_slices(prep, options, img);
  ChannelTarget deep_back;
  if (prep.deep_back) {
    img.depth_back.create(int(prep.data.height()), int(prep.data.width()), CV_32FC1);
    deep_back = {"", img.depth_back.ptr<float>(), 1, img.depth_back.step[0]};
  }
  decode_parts(prep, options, plan, prep.deep_back ? &deep_back : nullptr);
  for (const SlicePlan::Copy& c : plan.copies) {
    const int pair[2] = {c.from_component, c.to_component};
    cv::mixChannels(c.from, 1, c.to, 1, pair, 1);
  }
  for (auto& [alias, source] : plan.aliases) *alias = *source;
}

// Albedo and light are finite and >= 0: NaN, infinities and negatives (a renderer's
// filter ringing, a bad pass) would spread as negative or undefined light through the
// bounce and the composite. 0 instead, as for environment texels.
inline float light_or_zero(float v) { return v >= 0.0f && v <= std::numeric_limits<float>::max() ? v : 0.0f; }

// light_or_zero of every sample of a CV_32F image, rows in parallel.
void set_unusable_light_to_zero(cv::Mat& m, int threads) {
  if (m.empty()) return;
  CV_Assert(m.depth() == CV_32F);
  const int row_floats = m.cols * m.channels();
  parallel_rows(cv::Range(0, m.rows), threads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* p = m.ptr<float>(y);
      for (int i = 0; i < row_floats; ++i) p[i] = light_or_zero(p[i]);
    }
  });
}

// out = light_or_zero(a x b) per sample (out may be b; the product as cv::multiply rounds
// it), rows in parallel.
void multiply_light(const cv::Mat& a, const cv::Mat& b, cv::Mat& out, int threads) {
  CV_Assert(a.type() == CV_32FC3 && b.type() == CV_32FC3 && a.size() == b.size());
  if (out.data != b.data) out.create(b.size(), b.type());
  const int row_floats = b.cols * 3;
  parallel_rows(cv::Range(0, b.rows), threads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* pa = a.ptr<float>(y);
      const float* pb = b.ptr<float>(y);
      float* po = out.ptr<float>(y);
      for (int i = 0; i < row_floats; ++i) po[i] = light_or_zero(pb[i] * pa[i]);
    }
  });
}

// The foreground pass's constants from the camera and the resolved inputs.
ForegroundPass foreground_pass(const Prepared& prep) {
  const Camera& camera = prep.camera;
  const ResolvedInput* normal_in = prep.channels.find("normal");
  ForegroundPass pass;
  pass.width = int(prep.data.width());
  pass.far_view = camera.far_view;
  pass.has_background = prep.background_depth.has_value();
  pass.background = prep.background_depth.value_or(0.0f);
  pass.radial = prep.radial_depth;
  pass.perspective = camera.is_perspective();
  pass.normals_world = normal_in && normal_in->space == Space::world;
  // Normals transform with the inverse transpose (equal to the rotation for a rigid
  // world_to_view, right for any affine one); they are renormalised afterwards.
  pass.normal_to_view = glm::transpose(glm::inverse(glm::mat3(camera.world_to_view)));
  // The view-space point at planar depth 1 is affine in the pixel coordinates for every
  // projection whose clip.w does not depend on x and y (see Camera::view_from_pixel_depth),
  // so rays are stepped across the image instead of solved per pixel.
  pass.ray_origin = camera.view_from_pixel_depth({0.5f, 0.5f}, 1.0f);
  pass.ray_step_x = camera.view_from_pixel_depth({1.5f, 0.5f}, 1.0f) - pass.ray_origin;
  pass.ray_step_y = camera.view_from_pixel_depth({0.5f, 1.5f}, 1.0f) - pass.ray_origin;
  return pass;
}

// Adds the rows' counts in row order (the same sums for every thread count).
void add_row_counts(const std::vector<RowCounts>& rows, FrameInfo& info) {
  for (const RowCounts& r : rows) {
    info.foreground_pixels += r.foreground;
    info.nonfinite_pixels += r.nonfinite;
    info.repaired_normal_pixels += r.repaired;
    info.normals_facing_away_pixels += r.facing_away;
    if (r.foreground) {
      info.depth_min_view = info.foreground_pixels == r.foreground
                                ? r.depth_min
                                : std::min(info.depth_min_view, r.depth_min);
      info.depth_max_view = std::max(info.depth_max_view, r.depth_max);
    }
  }
}

// Whether normals taken as view space only by assumption (Prepared::normal_space_assumed)
// are not: more than kMaxFacingAwayOfViewNormals of the foreground normals face away from
// the eye (n . direction to the eye < 0 along each pixel's eye ray). Then a note says so.
bool assumed_view_normals_refuted(const Prepared& prep, FrameInfo& info) {
  const int64_t with_normal = info.foreground_pixels - info.repaired_normal_pixels;
  if (!prep.normal_space_assumed || with_normal <= 0) return false;
  const double away = double(info.normals_facing_away_pixels) / double(with_normal);
  if (!(away > kMaxFacingAwayOfViewNormals)) return false;
  std::ostringstream note;
  note.precision(3);
  note << "normal channels " << prep.channels.find("normal")->describe()
       << " are not view space: their space is not stated and the camera (" << info.camera_source
       << ") has no world transform, but " << 100.0 * away << "% of the foreground normals face away from the eye ("
       << info.normals_facing_away_pixels << " of " << with_normal
       << " pixels; view-space normals face it): normals rebuilt from depth. World-space normals are used with "
          "--map normal-space=world and a camera with a world transform (a sidecar, or worldToCamera/worldToNDC); "
          "--map normal-space=view keeps them as view space";
  info.notes.push_back(note.str());
  return true;
}

// Depth, mask and normals in the internal conventions (foreground_row over every row), and
// the counts. Foreground pixels with a zero normal are marked in normal_missing. Normals
// that fail the view-space check (assumed_view_normals_refuted) are left out: normal_view
// stays empty, to be rebuilt from depth.
void classify_foreground(const Prepared& prep, const ReadOptions& options, Images& img,
                         ReadResult& result) {
  GBuffer& g = result.gbuffer;
  const cv::Size size(int(prep.data.width()), int(prep.data.height()));
  const bool has_normals = !img.normal.empty();
  g.depth_view = img.depth;
  g.mask.create(size, CV_8UC1);
  cv::Mat repair;  // foreground pixels whose stored normal is (0, 0, 0)
  if (has_normals) repair = cv::Mat::zeros(size, CV_8UC1);
  std::vector<RowCounts> row_counts(size.height);
  const ForegroundPass pass = foreground_pass(prep);
  parallel_rows(cv::Range(0, size.height), options.threads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      row_counts[y] = foreground_row(
          pass, row_ray(pass, y),
          {g.depth_view.ptr<float>(y), g.mask.ptr<uint8_t>(y),
           has_normals ? img.normal.ptr<cv::Vec3f>(y) : nullptr,
           has_normals ? repair.ptr<uint8_t>(y) : nullptr});
  });
  FrameInfo& info = result.info;
  add_row_counts(row_counts, info);
  info.masked_pixels = int64_t(size.area()) - info.foreground_pixels;
  if (info.foreground_pixels == 0)
    info.notes.push_back(std::string(kWarningNote) + "no foreground pixel: " + std::string(kNoForeground) +
                         "; the terms are an empty frame's");
  if (has_normals && assumed_view_normals_refuted(prep, info)) {
    std::erase_if(info.uses, [](const ChannelUse& u) { return u.input == "normal"; });
    info.normals_reconstructed = true;
    info.repaired_normal_pixels = 0;
    return;
  }
  if (has_normals) g.normal_view = img.normal;
  if (info.repaired_normal_pixels > 0) g.normal_missing = repair;
}

// The foreground depth range as the file holds it (FrameInfo::depth_min_stored): a radial
// depth is the planar one times the length of the pixel's eye ray (planar_depth divided by
// it; the product is the stored value to a rounding).
void stored_depth_range(const Prepared& prep, const ReadOptions& options, const GBuffer& g, FrameInfo& info) {
  info.depth_min_stored = info.depth_min_view;
  info.depth_max_stored = info.depth_max_view;
  const ForegroundPass pass = foreground_pass(prep);
  if (!pass.radial || !pass.perspective || info.foreground_pixels == 0) return;
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<std::pair<float, float>> rows(g.depth_view.rows, {inf, -inf});
  parallel_rows(cv::Range(0, g.depth_view.rows), options.threads, [&](const cv::Range& range) {
    for (int y = range.start; y < range.end; ++y) {
      const float* depth = g.depth_view.ptr<float>(y);
      const uint8_t* mask = g.mask.ptr<uint8_t>(y);
      const glm::vec3 ray_row = row_ray(pass, y);
      for (int x = 0; x < g.depth_view.cols; ++x) {
        if (!mask[x]) continue;
        const float stored = depth[x] * glm::length(eye_ray(pass, ray_row, x));
        rows[y] = {std::min(rows[y].first, stored), std::max(rows[y].second, stored)};
      }
    }
  });
  info.depth_min_stored = inf;
  info.depth_max_stored = -inf;
  for (const auto& [lo, hi] : rows) {
    info.depth_min_stored = std::min(info.depth_min_stored, lo);
    info.depth_max_stored = std::max(info.depth_max_stored, hi);
  }
}

// The back-face depth in the depth's conventions (planar_depth), +inf off the foreground and
// where the stored value is background, never in front of the pixel's own depth (the far
// side of a surface is behind it; a back pass rendered at another precision may differ by
// a rounding).
//
// A deep part whose foreground pixels hold one surface each (a renderer that stores only
// the first opaque hit, as most do for opaque scenes) says nothing about what lies behind
// them: it gives no back layer, and the kernels assume their thickness as for a flat frame
// (+inf everywhere would make every surface solid to infinity, worse than that guess).
void back_layer_to_planar(const Prepared& prep, const ReadOptions& options, Images& img,
                          ReadResult& result) {
  if (img.depth_back.empty()) return;
  GBuffer& g = result.gbuffer;
  const ForegroundPass pass = foreground_pass(prep);
  std::atomic<bool> any_back_surface{false};
  parallel_rows(cv::Range(0, img.depth_back.rows), options.threads, [&](const cv::Range& rows) {
    bool found = false;
    for (int y = rows.start; y < rows.end; ++y) {
      float* back = img.depth_back.ptr<float>(y);
      const float* front = g.depth_view.ptr<float>(y);
      const uint8_t* mask = g.mask.ptr<uint8_t>(y);
      const glm::vec3 ray_row = row_ray(pass, y);
      for (int x = 0; x < img.depth_back.cols; ++x) {
        const float b = mask[x] ? planar_depth(pass, eye_ray(pass, ray_row, x), back[x])
                                : std::numeric_limits<float>::infinity();
        back[x] = std::max(b, front[x]);
        found |= std::isfinite(back[x]);
      }
    }
    if (found) any_back_surface = true;
  });
  if (prep.deep_back && !any_back_surface) {
    std::erase_if(result.info.uses, [](const ChannelUse& u) { return u.input == "depth_back"; });
    result.info.notes.push_back("no back layer: the deep samples of " + prep.channels.find("depth")->channels[0] +
                                " hold no second surface on any foreground pixel (--thickness is assumed)");
    result.info.back_layer.clear();
    return;
  }
  g.depth_back_view = img.depth_back;
}

// The positions pass to view space (non-finite and background positions become 0), or, when
// the frame has none, reported missing.
void positions_to_view(const Prepared& prep, const ReadOptions& options, Images& img,
                       ReadResult& result) {
  GBuffer& g = result.gbuffer;
  if (img.position.empty()) {
    result.info.positions_missing = true;
    return;
  }
  const ResolvedInput* position_in = prep.channels.find("position");
  const bool positions_world = position_in && position_in->space == Space::world;
  const Camera& camera = prep.camera;
  g.position_view = img.position;
  parallel_rows(cv::Range(0, g.position_view.rows), options.threads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      cv::Vec3f* p = g.position_view.ptr<cv::Vec3f>(y);
      const uint8_t* m = g.mask.ptr<uint8_t>(y);
      for (int x = 0; x < g.position_view.cols; ++x) {
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
}

// Albedo, lighting and the reference passes. Kernels multiply with albedo and lighting:
// non-finite and negative values become 0 (the reference passes are left as the renderer
// wrote them).
void shading_inputs(const ReadOptions& options, Images& img, GBuffer& g) {
  set_unusable_light_to_zero(img.albedo, options.threads);
  if (options.read_lighting) {
    if (!img.lighting.empty()) {
      g.lighting = img.lighting;
      set_unusable_light_to_zero(g.lighting, options.threads);
    } else if (!img.albedo.empty() && !img.diffdir.empty()) {
      // Sender radiance of a Lambertian pixel under the renderer's direct light:
      // albedo x direct irradiance-like pass (Cycles: DiffCol * DiffDir, docs/usage.md),
      // in the pass's own image unless a reference pass shares it.
      bool shared = false;
      for (const auto& [name, m] : img.references) shared = shared || m.data == img.diffdir.data;
      if (!shared) g.lighting = img.diffdir;
      multiply_light(img.albedo, img.diffdir, g.lighting, options.threads);
    }
  }
  if (options.read_albedo) g.albedo = img.albedo;
  if (options.read_references) {
    for (auto& [name, m] : img.references) g.references[name] = m;
  }
}

}  // namespace

ReadOptions depth_only(ReadOptions options) {
  options.read_normals = false;
  options.read_positions = false;
  options.read_albedo = false;
  options.read_lighting = false;
  options.read_references = false;
  options.read_depth_back = false;
  return options;
}

ReadResult inspect_gbuffer(const std::string& path, const ReadOptions& options) {
  ReadResult result;
  try {
    Prepared prep;
    if (prepare(path, options, result, prep)) result.gbuffer.camera = prep.camera;
  } catch (const std::exception& e) {
    fail_with(result, path, e);
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
    result.gbuffer.camera = prep.camera;
    result.gbuffer.data_origin_px = cv::Point(int(prep.data.min_x), int(prep.data.min_y));
    Images img;
    try {
      read_pixels(prep, options, img);
    } catch (const std::exception& e) {
      const char* what = read_failure(e, result.exhausted);
      result.error = path + ": cannot read pixels (" + what + "): " + e.what();
      return result;
    }
    classify_foreground(prep, options, img, result);
    stored_depth_range(prep, options, result.gbuffer, result.info);
    back_layer_to_planar(prep, options, img, result);
    if (options.read_positions) positions_to_view(prep, options, img, result);
    shading_inputs(options, img, result.gbuffer);
    return result;
  } catch (const std::exception& e) {
    fail_with(result, path, e);
  } catch (...) {
    result.error = path + ": unknown error while reading";
  }
  result.gbuffer = GBuffer{};
  return result;
}

}  // namespace ssdo
