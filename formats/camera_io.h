// Camera sources of a frame and their conversion to the internal Camera (core/camera.h):
// the JSON sidecar written beside Blender/Cycles dumps, and the OpenEXR standard header
// attributes worldToCamera / worldToNDC.
//
// Pixel grids. A camera is defined over the frame's display window (the full render);
// the kernels' pixel grid is the data window. `projection_for_data_window` re-targets an
// OpenGL-style projection from the first to the second, so crops and overscan keep the
// same rays per pixel.
#pragma once

#include <optional>
#include <string>

#include <glm/glm.hpp>

#include "core/camera.h"

namespace ssdo {

// An integer pixel rectangle in absolute EXR pixel coordinates, inclusive corners
// (the OpenEXR Box2i convention).
struct PixelBox {
  int min_x = 0, min_y = 0, max_x = -1, max_y = -1;
  int64_t width() const { return int64_t(max_x) - min_x + 1; }
  int64_t height() const { return int64_t(max_y) - min_y + 1; }
  bool operator==(const PixelBox&) const = default;
};

// Everything a camera.json sidecar says about a frame (see
// ../shared/gbuffers/README.md, "Coordinate conventions"). Matrices in the file are
// row-major and column-vector (p' = M p), camera looking down -Z: the same as our view space.
struct SidecarCamera {
  Camera camera;                          // over the sidecar's width x height grid
  int width_px = 0, height_px = 0;        // the render resolution the matrices refer to
  std::optional<std::string> depth_kind;  // "planar" | "radial"
  std::optional<float> ao_distance_world;
  std::optional<float> background_depth;  // depth value written on background pixels
  std::optional<std::string> normal_space;    // "world" | "camera" | "view"
  std::optional<std::string> position_space;  // "world" | "camera" | "view"
};

// Parses a sidecar file. Returns nullopt and sets *error (naming the file and the field)
// when the file cannot be read or a required field (projection, world_to_camera, width,
// height) is missing or malformed.
std::optional<SidecarCamera> read_camera_sidecar(const std::string& path, std::string* error);

// The sidecar conventionally beside a frame: "dir/NAME.exr" -> "dir/NAME.camera.json".
std::string sidecar_path_for(const std::string& exr_path);

// Re-targets an OpenGL-style projection whose NDC [-1, 1]^2 spans `display` (y up, top
// row of the display window at ndc_y = +1) to NDC spanning `data`. Identity when the boxes
// are equal.
glm::mat4 projection_for_data_window(const glm::mat4& view_to_clip_display,
                                     const PixelBox& display, const PixelBox& data);

// Non-standard header attributes carrying the clip distances next to worldToCamera /
// worldToNDC (OpenEXR has no standard attribute for them): written by write_outputs, read
// by read_gbuffer.
inline constexpr const char* kClipNearAttribute = "clipNear";
inline constexpr const char* kClipFarAttribute = "clipFar";

// Matrices as stored in the OpenEXR header (Imath M44f, row-vector convention p' = p M).
// Imath stores x[row][col] row by row; glm stores m[col][row] column by column, so the
// same 16 floats read as a glm matrix are exactly the column-vector form (p' = G p):
// no transpose is needed when copying between the two, element by element in memory order.
struct ExrCameraMatrices {
  glm::mat4 world_to_camera{1.0f};  // column-vector form of the worldToCamera attribute
  glm::mat4 world_to_ndc{1.0f};     // column-vector form of the worldToNDC attribute
};

// Builds a Camera from worldToCamera / worldToNDC.
//
// OpenEXR (ImfStandardAttributes.h, after RenderMan) defines camera space as left-handed,
// looking down +Z, x right, y up, and NDC as (0, 0) = upper-left and (1, 1) = lower-right
// corner of the display window, y down, after the homogeneous divide. Writers differ in
// practice (Arnold- and Blender-style exporters store a right-handed camera looking down
// -Z), so the axes are detected from the matrices rather than assumed:
// - viewing direction: the sign of camera z in the NDC w row (perspective; w = +z for
//   RenderMan, w = -z for a -Z camera). Orthographic cameras (w constant) cannot show it;
//   the OpenEXR convention (+Z) is assumed and said in *note;
// - x right / y up: the NDC motion of a camera-space step along +x / +y in front of the
//   camera.
// Camera space is then mapped to our view space (x right, y up, looking down -Z) by an
// axis sign flip, the NDC of the display window is re-targeted to the data window, the
// projection is scaled so that clip.w = -z_view (perspective) or 1 (orthographic), and its
// depth row (which NDC discards) is rebuilt OpenGL-style from near/far.
// near_view / far_view: clip distances if known (0 = unknown: 0.05 / 1000 fill the
// depth row, Camera::near_view/far_view stay 0).
// The optical axis must land inside the display window (OpenEXR NDC (0, 1) x (0, 1)): a
// worldToNDC in OpenGL's [-1, 1] convention (the axis at NDC (0, 0), y growing upwards) is
// converted to OpenEXR's, with a note; any other axis at or outside the window is an error.
// Returns nullopt with *error when the matrices are singular or not finite.
std::optional<Camera> camera_from_exr_matrices(const ExrCameraMatrices& m,
                                               const PixelBox& display, const PixelBox& data,
                                               float near_view, float far_view,
                                               std::string* error, std::string* note);

// The inverse, as written by write_outputs: worldToCamera in the OpenEXR convention
// (left-handed, +Z forward: our view space with z negated) and worldToNDC over a display
// window equal to the camera's width_px x height_px grid.
ExrCameraMatrices exr_matrices_from_camera(const Camera& camera);

// A perspective or orthographic OpenGL depth row (clip z) for near/far, written into
// view_to_clip whose w row is already normalised (w = -z or w = 1).
void set_gl_depth_row(glm::mat4& view_to_clip, float near_view, float far_view);

}  // namespace ssdo
