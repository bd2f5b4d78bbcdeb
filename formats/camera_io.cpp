#include "formats/camera_io.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "formats/input_file.h"

namespace ssdo {

namespace {

// Defaults for the OpenGL depth row when the source gives no clip distances; they match
// Camera::from_fov_x and only affect clip z, which no kernel reads.
constexpr float kDefaultNear = 0.05f;
constexpr float kDefaultFar = 1000.0f;

bool all_finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

// A row-major 4x4 JSON array -> glm (column-major, m[col][row]).
bool matrix_from_json(const nlohmann::json& j, glm::mat4& out) {
  if (!j.is_array() || j.size() != 4) return false;
  for (int r = 0; r < 4; ++r) {
    if (!j[r].is_array() || j[r].size() != 4) return false;
    for (int c = 0; c < 4; ++c) {
      if (!j[r][c].is_number()) return false;
      out[c][r] = j[r][c].get<float>();
    }
  }
  return all_finite(out);
}

// Whether b is a's inverse, as far as float matrices can be: b a's linear part within 1e-4
// of the identity, and its translation within 1e-5 of the poses' largest translation (a
// float pose 12 km from the origin is exact to about a millimetre, not to 1e-4 absolute).
bool inverse_of(const glm::mat4& a, const glm::mat4& b) {
  const glm::dmat4 product = glm::dmat4(b) * glm::dmat4(a);
  double reach = 1.0;
  for (int r = 0; r < 3; ++r) reach = std::max({reach, std::abs(double(a[3][r])), std::abs(double(b[3][r]))});
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) {
      const double tolerance = c == 3 && r < 3 ? 1e-5 * reach : 1e-4;
      if (!(std::abs(product[c][r] - (c == r ? 1.0 : 0.0)) <= tolerance)) return false;
    }
  return true;
}

// Why the 3x3 part of a world-to-camera matrix is not a rotation with one uniform scale
// (its rows, the camera's axes in the world, orthogonal and of equal length within 1e-3):
// empty when it is. A pose with unequal axes would shear the view's angles.
std::string not_a_pose(const glm::mat4& m) {
  const glm::dvec3 axis[3] = {glm::dvec3(m[0][0], m[1][0], m[2][0]), glm::dvec3(m[0][1], m[1][1], m[2][1]),
                              glm::dvec3(m[0][2], m[1][2], m[2][2])};
  const double lengths[3] = {glm::length(axis[0]), glm::length(axis[1]), glm::length(axis[2])};
  const double scale = (lengths[0] + lengths[1] + lengths[2]) / 3.0;
  for (int i = 0; i < 3; ++i) {
    if (!(std::abs(lengths[i] - scale) <= 1e-3 * scale))
      return "its axes are scaled unequally (" + std::to_string(lengths[0]) + ", " + std::to_string(lengths[1]) +
             ", " + std::to_string(lengths[2]) + ")";
    if (!(std::abs(glm::dot(axis[i], axis[(i + 1) % 3])) <= 1e-3 * scale * scale)) return "its axes are not orthogonal";
  }
  return {};
}

}  // namespace

std::string sidecar_path_for(const std::string& exr_path) {
  std::filesystem::path p(exr_path);
  p.replace_extension(".camera.json");
  return p.string();
}

namespace {

// Why a world-to-camera matrix (`name`, as its source calls it) is no rigid camera pose
// with a uniform scale: empty when it is one. The sidecar's must also be affine (its last
// row (0, 0, 0, 1)); a header's may carry any homogeneous scale.
std::string pose_error(const glm::mat4& pose, const std::string& name, bool affine) {
  if (!(std::abs(glm::determinant(glm::dmat4(pose))) > 1e-12))
    return name + " is singular (no camera pose maps the world onto view space)";
  if (affine &&
      !(std::max({std::abs(pose[0][3]), std::abs(pose[1][3]), std::abs(pose[2][3]), std::abs(pose[3][3] - 1.0f)}) <=
        1e-6f))
    return name + "'s last row is not (0, 0, 0, 1): not a camera pose (written column by column?)";
  if (const std::string why = not_a_pose(pose); !why.empty())
    return name + " is not a rotation with a uniform scale: " + why;
  return {};
}

// Why a sidecar's projection is none the kernels can use: empty when it is one.
std::string sidecar_projection_error(const glm::mat4& p) {
  if (p[2][3] == 0.0f && p[3][3] == 0.0f) return "\"projection\" has a zero w row";
  const float w_scale = std::max(std::abs(p[2][3]), std::abs(p[3][3]));
  if (!(std::abs(p[0][3]) <= 1e-6f * w_scale && std::abs(p[1][3]) <= 1e-6f * w_scale))
    return "\"projection\"'s w row depends on view-space x or y (written column by column?)";
  if (p[0][0] == 0.0f || p[1][1] == 0.0f) return "\"projection\" does not project view-space x and y";
  // Perspective: w = -z for a camera looking down -Z (OpenGL-style, as documented).
  if (p[2][3] > 0.0f)
    return "\"projection\" looks down +Z (w = +z); the sidecar's camera looks down -Z (OpenGL-style: w = -z)";
  // The transpose of an OpenGL perspective projection: its w row (0, 0, -2fn / (f - n), 0)
  // passes for a perspective one with a zoom of about 1 / 2n, but its z row's constant is
  // the original w's -1, which a projection scaled by any factor has only by chance.
  if (p[2][3] != 0.0f && std::abs(p[2][3]) != 1.0f && std::abs(p[3][2]) == 1.0f)
    return "\"projection\" looks transposed (its z row ends in " + std::to_string(p[3][2]) + " and w = " +
           std::to_string(p[2][3]) + " z): written column by column?";
  return {};
}

// Why the sidecar's distances or field of view describe no camera a frame was rendered
// with: empty when they do. The field of view as --fov takes it ([0.1, 179.9] degrees);
// clip distances 0 <= near < far; the AO distance and the background's depth positive.
std::string sidecar_values_error(const SidecarCamera& s, bool has_far) {
  const Camera& c = s.camera;
  if (!std::isfinite(c.near_view) || !std::isfinite(c.far_view) || c.near_view < 0.0f)
    return "\"clip_near\" and \"clip_far\" must be finite and not negative";
  if (has_far && !(c.far_view > c.near_view))
    return "\"clip_far\" (" + std::to_string(c.far_view) + ") must lie beyond \"clip_near\" (" +
           std::to_string(c.near_view) + ")";
  for (const auto& [key, value] :
       {std::pair{"ao_distance", s.ao_distance_world}, std::pair{"background_depth", s.background_depth}})
    if (value && !(std::isfinite(*value) && *value > 0.0f))
      return std::string("\"") + key + "\" must be a positive distance in scene units, not " + std::to_string(*value);
  const glm::mat4& p = c.view_to_clip;
  if (p[2][3] == 0.0f) return {};  // orthographic: no angle
  for (const auto& [axis, scale] : {std::pair{"horizontal", p[0][0]}, std::pair{"vertical", p[1][1]}}) {
    const double fov_deg = 2.0 * std::atan(1.0 / std::abs(double(scale))) * 180.0 / 3.14159265358979323846;
    if (!(fov_deg >= 0.1 && fov_deg <= 179.9))
      return std::string("\"projection\" gives a ") + axis + " field of view of " + std::to_string(fov_deg) +
             " degrees; a pinhole camera's lies within [0.1, 179.9]";
  }
  return {};
}

// The sidecar's camera in our conventions. One homogeneous scale: w = -z (perspective) or
// w = 1 (orthographic), as Camera's field of view and every reader of the matrix assume. A
// projection whose NDC x grows to the left or y downwards (Vulkan's clip space, or a frame
// stored bottom row first) describes the same rays per pixel as one that does not, with
// view-space x or y negated: the view space becomes ours (x right, y up), and the pose with
// it, so that every kernel's screen-to-view direction holds.
void normalise_sidecar_camera(Camera& camera) {
  glm::mat4& p = camera.view_to_clip;
  p = p * (p[2][3] != 0.0f ? -1.0f / p[2][3] : 1.0f / p[3][3]);
  const float sign_x = p[0][0] < 0.0f ? -1.0f : 1.0f, sign_y = p[1][1] < 0.0f ? -1.0f : 1.0f;
  if (sign_x > 0.0f && sign_y > 0.0f) return;
  const glm::mat4 flip(glm::vec4(sign_x, 0, 0, 0), glm::vec4(0, sign_y, 0, 0), glm::vec4(0, 0, 1, 0),
                       glm::vec4(0, 0, 0, 1));  // its own inverse
  p = p * flip;
  camera.world_to_view = flip * camera.world_to_view;
  camera.view_to_world = camera.view_to_world * flip;
}

// A sidecar's pixel count `key`: a whole number (640 or 640.0, as some exporters write every
// number) from 1 to 2^30; 0 when absent (or null), -1 for anything else.
int sidecar_pixels(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || j[key].is_null()) return 0;
  if (!j[key].is_number()) return -1;
  const double v = j[key].get<double>();
  return v >= 1 && v <= double(1 << 30) && v == std::floor(v) ? int(v) : -1;
}

// A sidecar's optional field given with another type, by name; empty when none is. Such a
// field is refused, never read as absent ("depth_kind": 1 would leave a radial depth taken
// for planar); null is absent.
std::string sidecar_field_type_error(const nlohmann::json& j) {
  for (const char* key : {"clip_near", "clip_far", "ao_distance", "background_depth"})
    if (j.contains(key) && !j[key].is_null() && !j[key].is_number())
      return std::string("\"") + key + "\" must be a number, not " + j[key].dump();
  for (const char* key : {"depth_kind", "normal_space", "position_space"})
    if (j.contains(key) && !j[key].is_null() && !j[key].is_string())
      return std::string("\"") + key + "\" must be a string, not " + j[key].dump();
  return {};
}

}  // namespace

std::optional<SidecarCamera> read_camera_sidecar(const std::string& path, std::string* error) {
  if (std::string e = input_file_error(path, "camera sidecar", kMaxTextFileBytes); !e.empty()) {
    *error = e;
    return std::nullopt;
  }
  std::ifstream in(path);
  if (!in) {
    *error = "cannot open camera sidecar " + path;
    return std::nullopt;
  }
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {  // where the text stops being JSON
    *error = "camera sidecar " + path + " is not valid JSON: " + e.what();
    return std::nullopt;
  }
  if (!j.is_object()) {
    *error = "camera sidecar " + path + " is not a JSON object";
    return std::nullopt;
  }
  auto fail = [&](const std::string& what) {
    *error = "camera sidecar " + path + ": " + what;
    return std::nullopt;
  };
  SidecarCamera s;
  if (!j.contains("projection") || !matrix_from_json(j["projection"], s.camera.view_to_clip))
    return fail("missing or malformed \"projection\" (row-major 4x4 numbers)");
  if (!j.contains("world_to_camera") ||
      !matrix_from_json(j["world_to_camera"], s.camera.world_to_view))
    return fail("missing or malformed \"world_to_camera\" (row-major 4x4 numbers)");
  if (const std::string e = pose_error(s.camera.world_to_view, "\"world_to_camera\"", true); !e.empty()) return fail(e);
  if (j.contains("camera_to_world")) {
    if (!matrix_from_json(j["camera_to_world"], s.camera.view_to_world))
      return fail("malformed \"camera_to_world\" (row-major 4x4 numbers)");
    if (!inverse_of(s.camera.world_to_view, s.camera.view_to_world))
      return fail("\"camera_to_world\" is not the inverse of \"world_to_camera\" (leave it out to derive it)");
  } else {
    s.camera.view_to_world = glm::inverse(s.camera.world_to_view);
  }
  s.width_px = sidecar_pixels(j, "width");
  s.height_px = sidecar_pixels(j, "height");
  if (s.width_px == 0 || s.height_px == 0) return fail("missing \"width\" / \"height\" (numbers of pixels)");
  if (s.width_px < 0 || s.height_px < 0)
    return fail("\"width\" and \"height\" must be whole numbers of pixels from 1 to 2^30");
  s.camera.width_px = s.width_px;
  s.camera.height_px = s.height_px;
  if (const std::string e = sidecar_field_type_error(j); !e.empty()) return fail(e);
  auto number = [&](const char* key) -> std::optional<float> {
    if (j.contains(key) && j[key].is_number()) return j[key].get<float>();
    return std::nullopt;
  };
  auto text = [&](const char* key) -> std::optional<std::string> {
    if (j.contains(key) && j[key].is_string()) return j[key].get<std::string>();
    return std::nullopt;
  };
  s.camera.near_view = number("clip_near").value_or(0.0f);
  s.camera.far_view = number("clip_far").value_or(0.0f);
  s.ao_distance_world = number("ao_distance");
  s.background_depth = number("background_depth");
  s.depth_kind = text("depth_kind");
  if (s.depth_kind && *s.depth_kind != "planar" && *s.depth_kind != "radial")
    return fail("\"depth_kind\" must be \"planar\" or \"radial\", not \"" + *s.depth_kind + "\"");
  s.normal_space = text("normal_space");
  s.position_space = text("position_space");
  for (const auto& [key, space] :
       {std::pair{"normal_space", s.normal_space}, std::pair{"position_space", s.position_space}})
    if (space && *space != "world" && *space != "view" && *space != "camera")
      return fail(std::string("\"") + key + "\" must be \"world\", \"view\" or \"camera\" (= view), not \"" + *space +
                  "\"");
  if (const std::string e = sidecar_projection_error(s.camera.view_to_clip); !e.empty()) return fail(e);
  normalise_sidecar_camera(s.camera);
  if (const std::string e = sidecar_values_error(s, number("clip_far").has_value()); !e.empty()) return fail(e);
  return s;
}

glm::mat4 projection_for_data_window(const glm::mat4& view_to_clip_display,
                                     const PixelBox& display, const PixelBox& data) {
  if (display == data) return view_to_clip_display;
  // Continuous absolute pixel x of display NDC x: disp.min_x + (ndc_x + 1) / 2 * disp_w;
  // data NDC: 2 (x_abs - data.min_x) / data_w - 1. Both maps are affine, so they compose
  // into one affine map of clip x (and y, with the row axis pointing down), applied to
  // the projection's x and y rows.
  const double disp_w = double(display.width()), disp_h = double(display.height());
  const double data_w = double(data.width()), data_h = double(data.height());
  const double sx = disp_w / data_w;
  const double tx = (2.0 * (display.min_x - data.min_x) + disp_w) / data_w - 1.0;
  const double sy = disp_h / data_h;
  const double ty = 1.0 - (2.0 * (display.min_y - data.min_y) + disp_h) / data_h;
  glm::mat4 a(1.0f);  // clip_data = A clip_display
  a[0][0] = float(sx);
  a[3][0] = float(tx);
  a[1][1] = float(sy);
  a[3][1] = float(ty);
  return a * view_to_clip_display;
}

void set_gl_depth_row(glm::mat4& p, float n, float f) {
  const bool perspective = p[2][3] != 0.0f;
  p[0][2] = 0.0f;
  p[1][2] = 0.0f;
  if (perspective) {
    p[2][2] = -(f + n) / (f - n);
    p[3][2] = -2.0f * f * n / (f - n);
  } else {
    p[2][2] = -2.0f / (f - n);
    p[3][2] = -(f + n) / (f - n);
  }
}

namespace {

// Why a header's worldToCamera and worldToNDC describe no camera: empty when they do.
std::string header_matrices_error(const ExrCameraMatrices& m) {
  if (!all_finite(m.world_to_camera) || !all_finite(m.world_to_ndc)) return "matrices are not finite";
  if (const std::string e = pose_error(m.world_to_camera, "worldToCamera", false); !e.empty()) return e;
  const glm::dmat4 camera_to_ndc = glm::dmat4(m.world_to_ndc) * glm::inverse(glm::dmat4(m.world_to_camera));
  const glm::dvec4 w_row(camera_to_ndc[0][3], camera_to_ndc[1][3], camera_to_ndc[2][3], camera_to_ndc[3][3]);
  const double w_scale = std::max(std::abs(w_row.z), std::abs(w_row.w));
  if (!(std::abs(w_row.x) <= 1e-6 * w_scale && std::abs(w_row.y) <= 1e-6 * w_scale))
    return "worldToNDC's w depends on camera-space x or y (no pinhole or orthographic camera; transposed?)";
  return {};
}

// What a header camera was taken for: its viewing direction and why.
std::string convention_note(bool perspective, double forward_z, double depth_slope) {
  if (!perspective && depth_slope == 0.0)
    return "orthographic header camera: viewing direction assumed +Z (OpenEXR convention)";
  if (!perspective)
    return std::string("orthographic header camera looks down ") + (forward_z > 0.0 ? "+Z" : "-Z") +
           " (where its NDC depth grows)";
  if (forward_z > 0.0) return "header camera looks down +Z (OpenEXR/RenderMan convention): z negated";
  return "header camera looks down -Z (right-handed, Blender/Arnold style)";
}

// OpenGL NDC (x right, y up, [-1, 1] over the display window) -> OpenEXR NDC (u right,
// v down, [0, 1]): u = (x + 1) / 2, v = (1 - y) / 2, on homogeneous coordinates.
glm::dmat4 uv_from_gl_ndc() {
  glm::dmat4 m(1.0);
  m[0][0] = 0.5;
  m[3][0] = 0.5;
  m[1][1] = -0.5;
  m[3][1] = 0.5;
  return m;
}

// The optical axis's image is within this of 0 in both NDC coordinates: the [-1, 1]
// convention's centre (float matrices round NDC to ~1e-7; a lens shift of 1e-5 of the
// frame is a 0.06 pixel shift of an 8K frame).
constexpr double kAxisAtOrigin = 1e-5;
// The optical axis's image within this of the display window's edge is "at" the edge: a
// camera of a tile or corner of a larger render, not of a whole frame.
constexpr double kAxisAtEdge = 1e-3;

// Where worldToNDC puts the optical axis (the image of the camera's viewing direction,
// forward_z along camera z), in OpenEXR NDC: (0, 0) and (1, 1) are the display window's
// upper-left and lower-right corners (ImfStandardAttributes.h, after RenderMan). A camera
// of a whole frame sees its axis inside the picture (a lens shift moves it, rarely far);
// a matrix written in OpenGL's [-1, 1] convention, as some exporters do, puts it at NDC
// (0, 0), a corner, and its y grows upwards. That case is converted to OpenEXR's (a note
// says so); an axis at or outside the display window otherwise is an error naming it.
std::string check_optical_axis(glm::dmat4& camera_to_ndc, double forward_z, const PixelBox& display,
                               std::string& note) {
  auto ndc_of = [&](glm::dvec3 p) {
    const glm::dvec4 q = camera_to_ndc * glm::dvec4(p, 1.0);
    return glm::dvec2(q.x, q.y) / q.w;
  };
  const glm::dvec2 axis = ndc_of({0.0, 0.0, forward_z});
  const bool y_up = ndc_of({0.0, 0.1, forward_z}).y > axis.y;
  if (std::abs(axis.x) <= kAxisAtOrigin && std::abs(axis.y) <= kAxisAtOrigin && y_up) {
    camera_to_ndc = uv_from_gl_ndc() * camera_to_ndc;
    note = "worldToNDC is in the [-1, 1] convention (its optical axis lands on NDC (0, 0), OpenEXR's upper-left "
           "corner, and its y grows upwards): converted to OpenEXR's [0, 1], y down";
    return {};
  }
  const auto inside = [](double t) { return t > kAxisAtEdge && t < 1.0 - kAxisAtEdge; };
  if (inside(axis.x) && inside(axis.y)) return {};
  // NDC to a thousandth, pixels to a tenth (and no "-0").
  const auto rounded = [](double v, double step) { return std::round(v / step) * step + 0.0; };
  std::ostringstream e;
  e << "worldToNDC puts the optical axis at NDC (" << rounded(axis.x, 1e-3) << ", " << rounded(axis.y, 1e-3)
    << "), pixel (" << rounded(display.min_x + axis.x * double(display.width()), 0.1) << ", "
    << rounded(display.min_y + axis.y * double(display.height()), 0.1) << "): at or outside the display window ("
    << display.width() << " x " << display.height() << " at (" << display.min_x << ", " << display.min_y
    << "); OpenEXR's NDC spans it from (0, 0) to (1, 1)), which no camera of a whole frame does (a matrix of "
       "another convention?)";
  return e.str();
}

}  // namespace

std::optional<Camera> camera_from_exr_matrices(const ExrCameraMatrices& m,
                                               const PixelBox& display, const PixelBox& data,
                                               float near_view, float far_view,
                                               std::string* error, std::string* note) {
  auto fail = [&](const std::string& what) {
    *error = "header camera (worldToCamera/worldToNDC): " + what;
    return std::nullopt;
  };
  if (const std::string e = header_matrices_error(m); !e.empty()) return fail(e);
  glm::dmat4 camera_to_ndc = glm::dmat4(m.world_to_ndc) * glm::inverse(glm::dmat4(m.world_to_camera));
  // NDC w row, as a function of camera-space (x, y, z, 1).
  const glm::dvec4 w_row(camera_to_ndc[0][3], camera_to_ndc[1][3], camera_to_ndc[2][3],
                         camera_to_ndc[3][3]);
  const bool perspective = std::abs(w_row.z) > 1e-6 * std::abs(w_row.w) && w_row.z != 0.0;
  if (!perspective && w_row.w == 0.0) return fail("worldToNDC has a zero w row");
  // An orthographic camera's w says nothing of its direction; its NDC depth (z / w) grows
  // away from the eye in every convention but a reversed one: the sign of its slope in
  // camera z, when it has one, else OpenEXR's +Z.
  const double depth_slope = camera_to_ndc[2][2] * w_row.w;
  const double forward_z = perspective ? (w_row.z > 0.0 ? 1.0 : -1.0) : depth_slope < 0.0 ? -1.0 : 1.0;
  std::string assumed = convention_note(perspective, forward_z, depth_slope);
  std::string converted;
  if (const std::string e = check_optical_axis(camera_to_ndc, forward_z, display, converted); !e.empty())
    return fail(e);
  if (!converted.empty()) assumed += "; " + converted;

  auto ndc_of = [&](glm::dvec3 p) {
    const glm::dvec4 q = camera_to_ndc * glm::dvec4(p, 1.0);
    return glm::dvec2(q.x, q.y) / q.w;
  };
  // Steps of 0.1 units at a distance of 1: inside any reasonable frustum, and the sign of
  // the NDC motion is all that is used.
  const glm::dvec2 c = ndc_of({0.0, 0.0, forward_z});
  const glm::dvec2 cx = ndc_of({0.1, 0.0, forward_z});
  const glm::dvec2 cy = ndc_of({0.0, 0.1, forward_z});
  if (!std::isfinite(c.x + c.y + cx.x + cy.y) || cx.x == c.x || cy.y == c.y)
    return fail("worldToNDC does not project camera-space x and y");
  const double sign_x = cx.x > c.x ? 1.0 : -1.0;  // NDC x grows to the right
  const double sign_y = cy.y < c.y ? 1.0 : -1.0;  // NDC y grows downwards
  if (sign_x < 0.0) assumed += "; camera x points left: x negated";
  if (sign_y < 0.0) assumed += "; camera y points down: y negated";
  glm::dmat4 d(1.0);  // camera -> view, its own inverse
  d[0][0] = sign_x;
  d[1][1] = sign_y;
  d[2][2] = -forward_z;

  // OpenEXR NDC -> OpenGL NDC of the display window: x = 2u - 1, y = 1 - 2v.
  glm::dmat4 view_to_clip = glm::inverse(uv_from_gl_ndc()) * camera_to_ndc * d;
  // Normalise the projective scale: w = -z_view (perspective) or w = 1 (orthographic).
  const double scale = perspective ? -view_to_clip[2][3] : view_to_clip[3][3];
  if (!(scale > 0.0) && !(scale < 0.0)) return fail("degenerate worldToNDC");
  view_to_clip = view_to_clip * (1.0 / scale);
  if (perspective && !(view_to_clip[2][3] < 0.0))
    return fail("inconsistent viewing direction in worldToNDC");

  Camera cam;
  cam.width_px = int(data.width());
  cam.height_px = int(data.height());
  cam.world_to_view = glm::mat4(d * glm::dmat4(m.world_to_camera));
  cam.view_to_world = glm::mat4(glm::inverse(d * glm::dmat4(m.world_to_camera)));
  cam.view_to_clip = projection_for_data_window(glm::mat4(view_to_clip), display, data);
  cam.near_view = near_view > 0.0f ? near_view : 0.0f;
  cam.far_view = far_view > 0.0f ? far_view : 0.0f;
  set_gl_depth_row(cam.view_to_clip, near_view > 0.0f ? near_view : kDefaultNear,
                   far_view > near_view && far_view > 0.0f ? far_view : kDefaultFar);
  if (!all_finite(cam.view_to_clip) || !all_finite(cam.view_to_world))
    return fail("matrices do not give a finite camera");
  if (note) *note = assumed;
  return cam;
}

ExrCameraMatrices exr_matrices_from_camera(const Camera& camera) {
  // Our view space -> OpenEXR camera space: negate z (left-handed, +Z forward).
  glm::mat4 flip_z(1.0f);
  flip_z[2][2] = -1.0f;
  const glm::mat4 uv_from_gl(uv_from_gl_ndc());  // OpenGL NDC -> OpenEXR NDC (exact in float)
  ExrCameraMatrices m;
  m.world_to_camera = flip_z * camera.world_to_view;
  m.world_to_ndc = uv_from_gl * camera.view_to_clip * camera.world_to_view;
  return m;
}

}  // namespace ssdo
