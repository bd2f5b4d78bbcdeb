// Reading a frame's G-buffer from an EXR file into the kernels' conventions.
//
// Channel profiles (detected automatically, or overridden by an explicit mapping):
// - "blender": Blender/Cycles multilayer names <ViewLayer>.Depth.Z, .Normal.XYZ (world),
//   .Position.XYZ (world), .DiffCol.RGB (albedo), .AO.R (reference "AO", CV_32FC1),
//   .DiffDir.RGB / .DiffInd.RGB (references "DiffDir" / "DiffInd", CV_32FC3).
//   lighting = DiffCol * DiffDir: the outgoing diffuse radiance of each pixel under the
//   renderer's direct light (DiffDir is irradiance-like, divided by albedo; see
//   ../shared/gbuffers/README.md), i.e. the sender radiance of the SSDO bounce.
// - "generic": single-layer names Z | depth.Z, N.XYZ | N.RGB | N.xyz, P.XYZ,
//   albedo.RGB | diffuse_albedo.RGB (Arnold-style AOVs). N and P are taken as world space
//   when the camera has a world transform (sidecar or header), as view space under a bare
//   --fov camera; a sidecar's "normal_space" / "position_space" or the mapping overrides.
//   Normals taken as view space only by that assumption are checked against the data: when
//   more than kMaxFacingAwayOfViewNormals of the foreground normals face away from the eye
//   they are not view space, and are dropped (rebuilt from depth) with a note.
// - "mapping": channels named by the caller (ChannelMapping); inputs it leaves empty keep
//   what the detected profile found.
// - back-face depth (GBuffer::depth_back_view), any profile: a flat channel <Layer>.DepthBack
//   (blender), Z.back or depth_back (generic), or mapped; or, in a deep part, the next
//   surface behind the nearest sample (below).
// Deep parts (DeepScanLine, DeepTile; OpenEXR "Interpreting OpenEXR Deep Pixels"): per
// pixel the nearest sample (smallest Z) gives depth and every other channel; the nearest
// sample whose Z lies beyond the nearest one's max(Z, ZBack) by more than
// kDeepSurfaceGapRelative of it gives the back-face depth (unless one is mapped); a part in
// which no foreground pixel has such a sample gives no back layer (a note says so). The
// samples of a pixel may be in any order. A pixel without samples is background.
// In a multi-part file, depth comes from ReadOptions::part or the first part holding a
// depth channel; other inputs from that part, else from another part. One a profile found
// in a part of another size is left out with a note; one mapped there is an error.
//
// Camera, in this order: a JSON sidecar (NAME.camera.json beside NAME.exr, or an explicit
// path), the OpenEXR header attributes worldToCamera + worldToNDC (M44f or M44d; either
// camera convention, detected: see formats/camera_io.h; optional float attributes clipNear /
// clipFar; header matrices that describe no camera, such as an optical axis at or outside
// the display window, are an error, or with a field of view a warning and that camera), or
// a horizontal field of view given by the caller. Sidecar and field of view
// refer to the display window; the projection is re-targeted to the data window, which is
// the pixel grid (row 0 = its top scanline).
//
// Conversions, done once here:
// - depth: radial -> planar along the eye ray. Background = non-finite, <= 0, >= 1e9,
//   beyond the far clip or equal to the sidecar's background_depth: mask 0, depth +inf.
//   The back-face depth gets the same conversion, is +inf where the pixel is background or
//   its own value is, and is raised to the pixel's depth where it lies in front of it.
// - normals: world -> view with the inverse transpose of world_to_view's 3x3, renormalised,
//   and flipped to face the camera when they point away from the eye (back faces or
//   unflipped shading normals; the kernels integrate over the visible hemisphere).
//   A foreground normal of (0, 0, 0) is reported (GBuffer::normal_missing, zero normal
//   left in place) and a frame without normals leaves GBuffer::normal_view empty: the
//   reader does no geometry; service/frame_inputs.h rebuilds both from depth.
// - NaN / Inf in depth or normals: the pixel is masked and counted (nonfinite_pixels);
//   NaN / Inf in albedo or lighting become 0; reference passes are left as stored.
// - Half channels are read as float.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/gbuffer.h"
#include "core/resource_failure.h"
#include "formats/exr_header_check.h"

namespace ssdo {

enum class DepthKind { automatic, planar, radial };
enum class Space { automatic, world, view };

// Explicit channel names, for renderers no profile knows. A name is either a full
// channel ("ViewLayer.Depth.Z") or a layer prefix whose components are found by suffix
// ("N" -> N.X N.Y N.Z | N.R N.G N.B | N.x N.y N.z). Empty = use the detected profile.
struct ChannelMapping {
  std::string depth;
  std::string depth_back;  // a back-face depth pass (GBuffer::depth_back_view)
  std::string normal;
  std::string position;
  std::string albedo;
  std::string lighting;
  std::map<std::string, std::string> references;  // name -> channel or layer
  Space normal_space = Space::automatic;
  Space position_space = Space::automatic;
};

// Who decodes the pixels of a scanline part stored with ZIP, ZIPS or no compression, with
// every channel at full resolution (x and y sampling 1):
// - libdeflate: the chunks are read raw with OpenEXRCore, inflated with libdeflate
//   (formats/exr_zip.h; OpenEXR 3.1 inflates with zlib, which is slower) and converted to
//   float here, over ReadOptions::threads strips of chunks;
// - openexr: OpenEXR's own decoder (Imf::InputPart), as for every other part.
// Both give bit-identical pixels, and a damaged chunk is an error with either (worded by
// each); the choice exists so that tests and benchmarks can compare them. Tiled, deep and
// subsampled parts and the other compressions always go to OpenEXR.
enum class ZipDecoder { libdeflate, openexr };

// Defaults read the depth, normals, albedo, lighting and reference passes of the chosen
// part with OpenEXR's global thread pool (ZIP parts: OpenCV's pool, see ZipDecoder).
// Deep samples of one pixel belong to different surfaces when their depths differ by more
// than this fraction of the nearer: a renderer writes one surface as several samples at
// nearly the same depth (fragments of one pixel, float rounding), while the two faces of an
// object 1% of its distance thick are 10x further apart.
inline constexpr float kDeepSurfaceGapRelative = 1e-3f;

struct ReadOptions {
  ChannelMapping mapping;
  std::string camera_json;              // explicit sidecar path; empty = look beside the frame
  std::optional<float> fov_x_deg;       // intrinsics when the file has no camera, degrees
  DepthKind depth_kind = DepthKind::automatic;  // automatic: sidecar/header says, else planar
  std::string part;                     // multi-part file: the part that holds depth (and the rest)
  bool read_normals = true;             // false: normal_view stays empty (a depth-only read)
  bool read_positions = false;          // positions pass, when present (else reported missing)
  bool read_albedo = true;
  bool read_lighting = true;
  bool read_references = true;          // e.g. the AO / DiffDir / DiffInd passes
  bool read_depth_back = true;          // the back-face depth, when the frame has one
  // Refused before anything is allocated (checked on every part's header, see
  // formats/exr_header_check.h): a data window, chunk, tile or row of tiles of more than
  // max_pixels pixels, or of more than max_decoded_bytes with every channel of its part
  // as stored (OpenEXR decodes them all).
  int64_t max_pixels = kDefaultMaxPixels;
  int64_t max_decoded_bytes = int64_t(1) << 34;  // 16 GiB: 64 float channels at max_pixels
  int threads = 0;                      // OpenEXR decoding threads (0 = its global pool) and
                                        // conversion strips and ZIP chunk strips (0 =
                                        // OpenCV's pool, 1 = serial)
  ZipDecoder zip_decoder = ZipDecoder::libdeflate;
};

struct ChannelUse {
  std::string input;     // "depth", "normal", "albedo", "reference:AO", ...
  std::string channels;  // e.g. "ViewLayer.Normal.{X,Y,Z}"
  std::string space;     // "world" | "view" | "" (not spatial)
};

// Normals of an unstated space under a camera without a world transform are taken as view
// space only while at most this fraction of the foreground normals face away from the eye.
// View-space normals of visible surfaces face it, but for back faces seen through open or
// single-sided meshes and smooth shading normals bent past a silhouette; the shared Cycles
// frames' normals, brought to view space with their cameras, face away on none of their
// pixels. Their world-space normals read as view space face away on 15% (greeble, a camera
// tilted down onto a floor whose world normal +Z happens to face the eye as a view normal)
// to 30% (depthgap, cornell 25%), and AO errors against the renderer's AO of 0.20 to 0.39
// (mean absolute) instead of 0.004 to 0.07, which normals rebuilt from depth match. Keeping
// wrong normals costs far more than rebuilding right ones: the limit sits well below 15%.
inline constexpr double kMaxFacingAwayOfViewNormals = 0.05;

// The start of a FrameInfo note that is a warning.
inline constexpr std::string_view kWarningNote = "warning: ";
// Why a frame has no foreground pixel (FrameInfo::foreground_pixels == 0).
inline constexpr std::string_view kNoForeground =
    "every depth sample is background (non-finite, below 1e-10 as in a negated depth pass, at least 1e9, or beyond "
    "the far clip)";

struct FrameInfo {
  std::string path;
  int width_px = 0, height_px = 0;            // data window size (= the pixel grid)
  int data_x = 0, data_y = 0;                 // data window origin
  int display_width_px = 0, display_height_px = 0;  // display window size
  int display_x = 0, display_y = 0;                 // display window origin
  std::vector<std::string> parts;             // part names (one entry "" for single part)
  std::string part;                           // the part depth was read from ("" = single part)
  std::vector<std::string> channels;          // every channel of the chosen part, with type
  std::string profile;                        // "blender" | "generic" | "mapping"
  std::string layer;                          // blender view layer prefix, e.g. "ViewLayer"
  std::vector<ChannelUse> uses;
  std::string camera_source;                  // "sidecar PATH" | "header worldToCamera/worldToNDC" | "--fov"
  float fov_x_deg = 0, fov_y_deg = 0;         // full fields of view of a perspective camera, degrees
  float view_width = 0, view_height = 0;      // an orthographic camera's view of the data window, scene units
  float near_view = 0, far_view = 0;          // clip distances, scene units (0 = unknown)
  std::string depth_kind;                     // "planar" | "radial", as converted
  // Where GBuffer::depth_back_view comes from: "channel NAME", "deep samples of NAME" or
  // "" (none read).
  std::string back_layer;
  // The frame has no normals: normal_view is left empty, to be reconstructed from depth.
  bool normals_reconstructed = false;
  // read_positions was asked and the frame has no positions pass: position_view is left
  // empty, to be computed from depth.
  bool positions_missing = false;
  std::optional<float> ao_distance_world;     // AO radius of the reference pass, if known
  float depth_min_view = 0, depth_max_view = 0;  // foreground depth range, planar
  // The same pixels' depth as the file holds it: the distance from the eye for a radial
  // depth (depth_kind "radial"), else the planar range above.
  float depth_min_stored = 0, depth_max_stored = 0;
  int64_t foreground_pixels = 0, masked_pixels = 0, nonfinite_pixels = 0;
  // Foreground pixels whose normal is (0, 0, 0) in the file (GBuffer::normal_missing), to
  // be replaced by the normal reconstructed from depth.
  int64_t repaired_normal_pixels = 0;
  // Foreground pixels whose normal, in view space, pointed away from the eye and was turned
  // around (back faces, unflipped shading normals, or normals of another space).
  int64_t normals_facing_away_pixels = 0;
  // Assumptions made while converting; those that begin with kWarningNote say the terms
  // are likely not what the user meant (shown without -v too).
  std::vector<std::string> notes;
};

struct ReadResult {
  GBuffer gbuffer;
  FrameInfo info;
  std::string error;  // empty on success; else a message naming file, part, channel or field
  // A failure that was memory or a thread running out, not the file (core/resource_failure.h).
  ResourceFailure exhausted = ResourceFailure::none;
  bool ok() const { return error.empty(); }
};

// Reads a frame. Never throws; every failure is an error message.
ReadResult read_gbuffer(const std::string& path, const ReadOptions& options = {});

// `options` reading depth (and the mask and camera) only: what a frame costs as another
// frame's extra view (GBuffer::views). Nothing else is converted or held.
ReadOptions depth_only(ReadOptions options);

// Reads only the header: profile, channels, camera source (info.* filled, gbuffer empty).
ReadResult inspect_gbuffer(const std::string& path, const ReadOptions& options = {});

// One channel of an EXR part read into one component of a float image.
struct ChannelComponent {
  std::string channel;
  int component = 0;
};

// read_gbuffer's own decoder for other images (an environment map): reads `channels` of
// the first part of the EXR at `path` into `image` (CV_32F, any channel count, the data
// window's size, allocated by the caller; other components are left as they are), half
// converted to float as OpenEXR does. False, with nothing read, when the part is not one
// this decoder reads (tiled, deep, another compression, a channel missing or of type
// uint, another size): the caller reads it with OpenEXR. Throws on a damaged chunk. The
// file's headers must have passed check_exr_headers.
bool read_scanline_channels(const std::string& path, std::span<const ChannelComponent> channels,
                            cv::Mat& image, int threads = 0);

}  // namespace ssdo
