// Camera sources: sidecar parsing, data window re-targeting, OpenEXR header matrices in
// both camera conventions.
#include "formats/camera_io.h"

#include <glm/gtc/matrix_transform.hpp>

#include "formats_test_util.h"

namespace ssdo::test {
namespace {

void expect_mat_near(const glm::mat4& a, const glm::mat4& b, float tol) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_NEAR(a[c][r], b[c][r], tol) << "[" << c << "][" << r << "]";
}

Camera posed_camera(int w, int h, float fov) {
  Camera cam = Camera::from_fov_x(w, h, fov, 0.05f, 1000.0f);
  glm::mat4 v2w(1.0f);
  const float a = glm::radians(-20.0f);  // pitch down 20 degrees
  v2w[1] = glm::vec4(0, std::cos(a), std::sin(a), 0);
  v2w[2] = glm::vec4(0, -std::sin(a), std::cos(a), 0);
  v2w[3] = glm::vec4(1, 2, 3, 1);
  cam.view_to_world = v2w;
  cam.world_to_view = glm::inverse(v2w);
  return cam;
}

TEST(CameraSidecar, CornellMatchesTheJsonRowMajorMatrices) {
  const fs::path path = gbuffer_dir() / "cornell.camera.json";
  SSDO_SKIP_WITHOUT(path);
  std::string error;
  const auto s = read_camera_sidecar(path.string(), &error);
  ASSERT_TRUE(s) << error;
  EXPECT_EQ(s->width_px, 640);
  EXPECT_EQ(s->height_px, 360);
  // JSON projection[0][0] = 1.5697 (row 0, col 0); [2][3] = -0.100005 is row 2, column 3,
  // i.e. glm m[3][2].
  EXPECT_FLOAT_EQ(s->camera.view_to_clip[0][0], 1.569685459136963f);
  EXPECT_FLOAT_EQ(s->camera.view_to_clip[3][2], -0.10000500082969666f);
  EXPECT_FLOAT_EQ(s->camera.view_to_clip[2][3], -1.0f);
  // world_to_camera row 1 column 3 (translation y) = -1.4569944.
  EXPECT_FLOAT_EQ(s->camera.world_to_view[3][1], -1.4569944143295288f);
  EXPECT_FLOAT_EQ(s->camera.view_to_world[3][1], -3.0f);
  EXPECT_FLOAT_EQ(s->camera.near_view, 0.05f);
  EXPECT_FLOAT_EQ(s->camera.far_view, 1000.0f);
  EXPECT_EQ(s->depth_kind.value_or(""), "planar");
  EXPECT_FLOAT_EQ(s->ao_distance_world.value_or(0), 1.0f);
  EXPECT_FLOAT_EQ(s->background_depth.value_or(0), 1e10f);
  // The camera at (0, -3, 1.5) maps to the view-space origin.
  const glm::vec3 eye = s->camera.view_from_world_point({0.0f, -3.0f, 1.5f});
  EXPECT_NEAR(glm::length(eye), 0.0f, 1e-5f);
}

TEST(CameraSidecar, MalformedSidecarsNameTheField) {
  ScratchDir dir;
  std::string error;
  EXPECT_FALSE(read_camera_sidecar((dir / "none.json").string(), &error));
  EXPECT_NE(error.find("none.json"), std::string::npos);
  std::ofstream(dir / "bad.json") << "{ not json";
  EXPECT_FALSE(read_camera_sidecar((dir / "bad.json").string(), &error));
  // Where the text stops being JSON.
  EXPECT_NE(error.find("bad.json is not valid JSON: [json.exception.parse_error.101] parse error at line 1, column 4"),
            std::string::npos)
      << error;
  std::ofstream(dir / "list.json") << "[1, 2]";
  EXPECT_FALSE(read_camera_sidecar((dir / "list.json").string(), &error));
  EXPECT_NE(error.find("list.json is not a JSON object"), std::string::npos) << error;
  std::ofstream(dir / "noproj.json") << R"({"width": 4, "height": 4})";
  EXPECT_FALSE(read_camera_sidecar((dir / "noproj.json").string(), &error));
  EXPECT_NE(error.find("\"projection\""), std::string::npos) << error;
  std::ofstream(dir / "short.json")
      << R"({"projection": [[1,0,0],[0,1,0],[0,0,1]], "world_to_camera": [], "width": 4, "height": 4})";
  EXPECT_FALSE(read_camera_sidecar((dir / "short.json").string(), &error));
  EXPECT_NE(error.find("\"projection\""), std::string::npos) << error;
}

// A glm matrix as the sidecar's row-major JSON.
nlohmann::json row_major(const glm::mat4& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m[0][r], m[1][r], m[2][r], m[3][r]});
  return rows;
}

// A sidecar of `cam` (without camera_to_world).
nlohmann::json sidecar_of(const Camera& cam) {
  return {{"projection", row_major(cam.view_to_clip)},
          {"world_to_camera", row_major(cam.world_to_view)},
          {"width", cam.width_px},
          {"height", cam.height_px}};
}

// Whether sidecar j, written to DIR/cam.json, is read (error: why not).
bool reads_sidecar(const ScratchDir& dir, const nlohmann::json& j, std::string& error) {
  const fs::path path = dir / "cam.json";
  std::ofstream(path) << j.dump();
  return read_camera_sidecar(path.string(), &error).has_value();
}

// Sidecars whose numbers parse but describe no camera are refused, each naming its field;
// a pose far from the origin with its float inverse is accepted.
TEST(CameraSidecar, SidecarsThatDescribeNoCameraNameTheField) {
  ScratchDir dir;
  Camera cam = posed_camera(64, 48, 60.0f);
  cam.view_to_world[3] = glm::vec4(12000.0f, -3000.0f, 150.0f, 1.0f);  // a set 12 km out
  cam.world_to_view = glm::inverse(cam.view_to_world);
  nlohmann::json valid = sidecar_of(cam);
  valid["camera_to_world"] = row_major(cam.view_to_world);
  auto read = [&](const nlohmann::json& j, std::string& error) { return reads_sidecar(dir, j, error); };
  std::string error;
  ASSERT_TRUE(read(valid, error)) << error;

  nlohmann::json singular = valid;
  singular["world_to_camera"] = row_major(glm::mat4(0.0f));
  singular.erase("camera_to_world");
  EXPECT_FALSE(read(singular, error));
  EXPECT_NE(error.find("\"world_to_camera\" is singular"), std::string::npos) << error;

  nlohmann::json other_pose = valid;
  glm::mat4 moved = cam.view_to_world;
  moved[3].x += 1.0f;  // a metre off: another camera
  other_pose["camera_to_world"] = row_major(moved);
  EXPECT_FALSE(read(other_pose, error));
  EXPECT_NE(error.find("\"camera_to_world\" is not the inverse of \"world_to_camera\""), std::string::npos)
      << error;

  nlohmann::json flat = valid;
  glm::mat4 p = cam.view_to_clip;
  p[1][1] = 0.0f;
  flat["projection"] = row_major(p);
  EXPECT_FALSE(read(flat, error));
  EXPECT_NE(error.find("does not project view-space x and y"), std::string::npos) << error;

  nlohmann::json backwards = valid;
  p = cam.view_to_clip;
  p[2][3] = 1.0f;  // w = +z: a camera looking down +Z
  backwards["projection"] = row_major(p);
  EXPECT_FALSE(read(backwards, error));
  EXPECT_NE(error.find("looks down +Z"), std::string::npos) << error;

  // A size written as a float (as some exporters write every number) is the same size;
  // a fraction, 0 or more than 2^30 is not a size.
  nlohmann::json floats = valid;
  floats["width"] = 64.0;
  floats["height"] = 48.0;
  ASSERT_TRUE(read(floats, error)) << error;
  EXPECT_EQ(read_camera_sidecar((dir / "cam.json").string(), &error)->width_px, 64);
  for (const nlohmann::json& width : {nlohmann::json(64.5), nlohmann::json(0), nlohmann::json(1e12),
                                      nlohmann::json(-64)}) {
    nlohmann::json odd = valid;
    odd["width"] = width;
    EXPECT_FALSE(read(odd, error)) << width;
    EXPECT_NE(error.find("\"width\" and \"height\" must be whole numbers of pixels from 1 to 2^30"),
              std::string::npos)
        << error;
  }
  // A field of another type is refused by name, never taken as absent; null is absent.
  for (const auto& [key, value] : std::vector<std::pair<std::string, nlohmann::json>>{
           {"depth_kind", 1}, {"depth_kind", {"radial"}}, {"ao_distance", "0.25"}, {"background_depth", "7.0"},
           {"normal_space", true}, {"clip_far", "3.5"}, {"width", "64"}}) {
    nlohmann::json typed = valid;
    typed[key] = value;
    EXPECT_FALSE(read(typed, error)) << key;
    EXPECT_NE(error.find("\"" + key + "\""), std::string::npos) << error;
  }
  nlohmann::json nulls = valid;
  nulls["ao_distance"] = nullptr;
  nulls["depth_kind"] = nullptr;
  EXPECT_TRUE(read(nulls, error)) << error;
  nlohmann::json sizeless = valid;
  sizeless.erase("height");
  EXPECT_FALSE(read(sizeless, error));
  EXPECT_NE(error.find("missing \"width\" / \"height\""), std::string::npos) << error;
}

// Matrices written column by column, unequal axis scales and unknown spaces are refused,
// naming the field.
TEST(CameraSidecar, TransposedOrShearedMatricesAndUnknownSpacesAreRefused) {
  ScratchDir dir;
  const Camera cam = posed_camera(64, 48, 60.0f);
  const nlohmann::json valid = sidecar_of(cam);
  auto read = [&](const nlohmann::json& j, std::string& error) { return reads_sidecar(dir, j, error); };
  std::string error;
  ASSERT_TRUE(read(valid, error)) << error;
  nlohmann::json j = valid;
  j["world_to_camera"] = row_major(glm::transpose(cam.world_to_view));
  EXPECT_FALSE(read(j, error));
  EXPECT_NE(error.find("\"world_to_camera\"'s last row is not (0, 0, 0, 1)"), std::string::npos) << error;
  j = valid;
  j["world_to_camera"] = row_major(glm::scale(glm::mat4(1.0f), glm::vec3(1.0f, 2.0f, 1.0f)) * cam.world_to_view);
  EXPECT_FALSE(read(j, error));
  EXPECT_NE(error.find("scaled unequally"), std::string::npos) << error;
  j = valid;
  j["world_to_camera"] = row_major(glm::scale(glm::mat4(1.0f), glm::vec3(100.0f)) * cam.world_to_view);
  EXPECT_TRUE(read(j, error)) << error;  // centimetres: a uniform scale
  j = valid;
  j["projection"] = row_major(glm::transpose(cam.view_to_clip));
  EXPECT_FALSE(read(j, error));
  EXPECT_NE(error.find("\"projection\" looks transposed"), std::string::npos) << error;
  glm::mat4 shifted = cam.view_to_clip;
  shifted[2][0] = 0.1f;  // a lens shift
  j["projection"] = row_major(glm::transpose(shifted));
  EXPECT_FALSE(read(j, error));
  EXPECT_NE(error.find("\"projection\" looks transposed"), std::string::npos) << error;
  glm::mat4 ortho(1.0f);  // an orthographic projection shifted in x: its transpose's w depends on x
  ortho[0][0] = 0.5f, ortho[1][1] = 0.6f, ortho[2][2] = -0.01f, ortho[3][0] = 0.1f, ortho[3][2] = -1.001f;
  j["projection"] = row_major(ortho);
  EXPECT_TRUE(read(j, error)) << error;
  j["projection"] = row_major(glm::transpose(ortho));
  EXPECT_FALSE(read(j, error));
  EXPECT_NE(error.find("w row depends on view-space x or y"), std::string::npos) << error;
  j["projection"] = row_major(2.0f * shifted);  // the same projection, homogeneously scaled
  ASSERT_TRUE(read(j, error)) << error;
  {
    std::string e;
    const auto scaled = read_camera_sidecar((dir / "cam.json").string(), &e);
    ASSERT_TRUE(scaled) << e;
    expect_mat_near(scaled->camera.view_to_clip, shifted, 1e-6f);  // w = -z again
  }
  for (const char* key : {"normal_space", "position_space"}) {
    j = valid;
    j[key] = "World";
    EXPECT_FALSE(read(j, error)) << key;
    EXPECT_NE(error.find(std::string("\"") + key + "\" must be \"world\", \"view\" or \"camera\""), std::string::npos)
        << error;
    j[key] = "camera";
    EXPECT_TRUE(read(j, error)) << error;
  }
}

// Distances and angles no camera renders with: each refused naming its field (an all-white
// frame or a silently ignored AO distance otherwise).
TEST(CameraSidecar, ClipDistancesAoDistanceAndFieldOfViewOutsideACamerasAreRefused) {
  ScratchDir dir;
  const Camera cam = posed_camera(64, 48, 60.0f);
  const nlohmann::json valid = sidecar_of(cam);
  std::string error;
  auto refused = [&](const nlohmann::json& j) {
    return reads_sidecar(dir, j, error) ? std::string("accepted") : error.substr(error.find(": ") + 2);
  };
  nlohmann::json j = valid;
  j["clip_near"] = 0.1, j["clip_far"] = 100.0, j["ao_distance"] = 0.5, j["background_depth"] = 1e10;
  ASSERT_EQ(refused(j), "accepted");
  j["clip_far"] = 0.1;
  EXPECT_EQ(refused(j), "\"clip_far\" (0.100000) must lie beyond \"clip_near\" (0.100000)");
  j["clip_near"] = 5.0, j["clip_far"] = 1.0;
  EXPECT_EQ(refused(j), "\"clip_far\" (1.000000) must lie beyond \"clip_near\" (5.000000)");
  j = valid;
  j["clip_near"] = -1.0;
  EXPECT_EQ(refused(j), "\"clip_near\" and \"clip_far\" must be finite and not negative");
  for (const double bad : {0.0, -1.0}) {
    j = valid;
    j["ao_distance"] = bad;
    EXPECT_NE(refused(j).find("\"ao_distance\" must be a positive distance in scene units"), std::string::npos);
    j = valid;
    j["background_depth"] = bad;
    EXPECT_NE(refused(j).find("\"background_depth\" must be a positive distance"), std::string::npos);
  }
  for (const float scale : {1e-30f, 1e30f}) {  // 180 and 0 degrees
    glm::mat4 p = cam.view_to_clip;
    p[0][0] = scale;
    j = valid;
    j["projection"] = row_major(p);
    EXPECT_NE(refused(j).find("\"projection\" gives a horizontal field of view of"), std::string::npos) << scale;
  }
}

// A projection whose NDC y grows downwards (Vulkan's clip space; a frame stored bottom row
// first) or x to the left describes the same rays per pixel: read as our camera with the
// view's axis negated, so every pixel sees the same world point and the projection's
// scales are positive (the kernels' screen-to-view directions assume them).
TEST(CameraSidecar, AProjectionWithFlippedAxesKeepsTheRaysPerPixel) {
  ScratchDir dir;
  const Camera cam = posed_camera(64, 48, 60.0f);
  for (const glm::vec3 flip : {glm::vec3(1, -1, 1), glm::vec3(-1, 1, 1), glm::vec3(-1, -1, 1)}) {
    // The stored frame is mirrored along the flipped axes: pixel (x, y) of the flipped
    // camera is pixel (w - 1 - x, y) or (x, h - 1 - y) of the original.
    glm::mat4 p = cam.view_to_clip;
    for (int c = 0; c < 4; ++c) p[c][0] *= flip.x, p[c][1] *= flip.y;
    nlohmann::json j = sidecar_of(cam);
    j["projection"] = row_major(p);
    std::ofstream(dir / "cam.json") << j.dump();
    std::string error;
    const auto s = read_camera_sidecar((dir / "cam.json").string(), &error);
    ASSERT_TRUE(s) << error;
    EXPECT_GT(s->camera.view_to_clip[0][0], 0.0f);
    EXPECT_GT(s->camera.view_to_clip[1][1], 0.0f);
    expect_mat_near(s->camera.view_to_world * s->camera.world_to_view, glm::mat4(1.0f), 1e-5f);
    for (const glm::vec3 world : {glm::vec3(1.3f, 7.0f, 2.5f), glm::vec3(-0.4f, 9.0f, 4.0f)}) {
      const glm::vec4 a = cam.view_to_clip * cam.world_to_view * glm::vec4(world, 1.0f);
      const glm::vec4 b = s->camera.view_to_clip * s->camera.world_to_view * glm::vec4(world, 1.0f);
      EXPECT_NEAR(b.x / b.w, flip.x * a.x / a.w, 1e-5f);
      EXPECT_NEAR(b.y / b.w, flip.y * a.y / a.w, 1e-5f);
    }
  }
}

TEST(CameraSidecar, PathBesideTheFrame) {
  EXPECT_EQ(sidecar_path_for("/a/b/shot.0001.exr"), "/a/b/shot.0001.camera.json");
  EXPECT_EQ(sidecar_path_for("cornell.exr"), "cornell.camera.json");
}

TEST(ProjectionForDataWindow, IdentityAndCropKeepRays) {
  const Camera full = Camera::from_fov_x(100, 80, 60.0f);
  const PixelBox display{0, 0, 99, 79};
  expect_mat_near(projection_for_data_window(full.view_to_clip, display, display), full.view_to_clip, 0);
  // A crop 30 x 20 at (50, 10) and an overscan 120 x 100 at (-10, -10).
  for (const PixelBox data : {PixelBox{50, 10, 79, 29}, PixelBox{-10, -10, 109, 89}}) {
    Camera crop = full;
    crop.width_px = int(data.width());
    crop.height_px = int(data.height());
    crop.view_to_clip = projection_for_data_window(full.view_to_clip, display, data);
    for (const glm::vec2 px : {glm::vec2(0.5f, 0.5f), glm::vec2(13.25f, 7.75f)}) {
      const glm::vec3 a = crop.view_from_pixel_depth(px, 2.0f);
      const glm::vec3 b = full.view_from_pixel_depth(px + glm::vec2(data.min_x, data.min_y), 2.0f);
      EXPECT_NEAR(glm::length(a - b), 0.0f, 1e-5f);
    }
  }
}

TEST(HeaderMatrices, WrittenMatricesReadBackToTheSameCamera) {
  const Camera cam = posed_camera(64, 48, 70.0f);
  const ExrCameraMatrices m = exr_matrices_from_camera(cam);
  // The OpenEXR convention: a point in front of the camera has positive camera z.
  const glm::vec3 front_world = cam.world_from_view_direction({0, 0, -1}) * 5.0f +
                                glm::vec3(cam.view_to_world[3]);
  EXPECT_GT((m.world_to_camera * glm::vec4(front_world, 1.0f)).z, 0.0f);
  // NDC (0, 0) is the upper-left corner: the top-left pixel centre projects near it.
  const glm::vec3 p = glm::vec3(cam.view_to_world * glm::vec4(cam.view_from_pixel_depth({0.5f, 0.5f}, 3.0f), 1.0f));
  const glm::vec4 q = m.world_to_ndc * glm::vec4(p, 1.0f);
  EXPECT_NEAR(q.x / q.w, 0.5f / 64.0f, 1e-5f);
  EXPECT_NEAR(q.y / q.w, 0.5f / 48.0f, 1e-5f);

  const PixelBox box{0, 0, 63, 47};
  std::string error, note;
  const auto back = camera_from_exr_matrices(m, box, box, 0.05f, 1000.0f, &error, &note);
  ASSERT_TRUE(back) << error;
  EXPECT_NE(note.find("+Z"), std::string::npos) << note;
  expect_mat_near(back->view_to_clip, cam.view_to_clip, 1e-5f);
  expect_mat_near(back->world_to_view, cam.world_to_view, 1e-5f);
}

TEST(HeaderMatrices, MinusZCameraAndMirroredAxesAreDetected) {
  const Camera cam = posed_camera(64, 48, 50.0f);
  const ExrCameraMatrices exr = exr_matrices_from_camera(cam);
  const PixelBox box{0, 0, 63, 47};
  // -Z camera (our view space stored as is), and one with camera y pointing down.
  glm::mat4 flip_y(1.0f);
  flip_y[1][1] = -1.0f;
  for (const glm::mat4& camera_from_view : {glm::mat4(1.0f), flip_y}) {
    ExrCameraMatrices m = exr;
    m.world_to_camera = camera_from_view * cam.world_to_view;
    std::string error, note;
    const auto back = camera_from_exr_matrices(m, box, box, 0.0f, 0.0f, &error, &note);
    ASSERT_TRUE(back) << error;
    EXPECT_NE(note.find("-Z"), std::string::npos) << note;
    expect_mat_near(back->world_to_view, cam.world_to_view, 1e-5f);
    for (int c = 0; c < 4; ++c)
      for (int r : {0, 1, 3}) EXPECT_NEAR(back->view_to_clip[c][r], cam.view_to_clip[c][r], 1e-5f);
    EXPECT_EQ(back->near_view, 0.0f);  // unknown clips stay unknown
  }
}

// A worldToNDC written in OpenGL's [-1, 1] convention (clip = P view, y up: the optical
// axis at NDC (0, 0), OpenEXR's upper-left corner) is recognised and converted, with a note;
// read as OpenEXR's it was a camera of half the field of view looking at a corner.
TEST(HeaderMatrices, MinusOneToOneNdcIsConverted) {
  const Camera cam = posed_camera(64, 48, 50.0f);
  const PixelBox box{0, 0, 63, 47};
  ExrCameraMatrices m;
  m.world_to_camera = cam.world_to_view;  // -Z camera, as Arnold- and Blender-style writers store it
  m.world_to_ndc = cam.view_to_clip * cam.world_to_view;
  std::string error, note;
  const auto back = camera_from_exr_matrices(m, box, box, 0.0f, 0.0f, &error, &note);
  ASSERT_TRUE(back) << error;
  EXPECT_NE(note.find("worldToNDC is in the [-1, 1] convention"), std::string::npos) << note;
  expect_mat_near(back->world_to_view, cam.world_to_view, 1e-5f);
  for (int c = 0; c < 4; ++c)
    for (int r : {0, 1, 3}) EXPECT_NEAR(back->view_to_clip[c][r], cam.view_to_clip[c][r], 1e-5f);
  EXPECT_NEAR(back->fov_x_deg(), 50.0f, 1e-3f);
}

// Any other worldToNDC that puts the optical axis at or outside the display window is
// refused, naming where the axis lands: a [-1, 1] matrix with a lens shift, or with y down
// (the axis at a corner in either case); an OpenEXR matrix whose axis is at a corner (a
// camera of a tile of a larger render). A lens shift keeping the axis inside is a camera.
TEST(HeaderMatrices, OpticalAxisAtOrOutsideTheDisplayWindowIsRefused) {
  const Camera cam = posed_camera(64, 48, 50.0f);
  const PixelBox box{0, 0, 63, 47};
  auto shifted = [&](float x_ndc, float y_ndc) {  // OpenGL NDC of the optical axis
    glm::mat4 p = cam.view_to_clip;
    p[2][0] = -x_ndc;  // x_clip gains -x_ndc z_view = x_ndc w
    p[2][1] = -y_ndc;
    return p;
  };
  glm::mat4 flip_y(1.0f);
  flip_y[1][1] = -1.0f;
  glm::mat4 uv_from_gl(1.0f);
  uv_from_gl[0][0] = 0.5f, uv_from_gl[3][0] = 0.5f, uv_from_gl[1][1] = -0.5f, uv_from_gl[3][1] = 0.5f;
  struct Case {
    glm::mat4 camera_to_ndc;
    const char* where;  // the axis's NDC as the error gives it; empty: a camera
  };
  const Case cases[] = {
      {shifted(0.25f, 0.0f), "NDC (0.25, 0), pixel (16, 0)"},
      {flip_y * cam.view_to_clip, "NDC (0, 0), pixel (0, 0)"},
      {uv_from_gl * shifted(-1.0f, 1.0f), "NDC (0, 0), pixel (0, 0)"},
      {uv_from_gl * shifted(0.5f, -0.4f), ""},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.where);
    ExrCameraMatrices m;
    m.world_to_camera = cam.world_to_view;
    m.world_to_ndc = c.camera_to_ndc * cam.world_to_view;
    std::string error, note;
    const auto back = camera_from_exr_matrices(m, box, box, 0.0f, 0.0f, &error, &note);
    if (*c.where == 0) {
      ASSERT_TRUE(back) << error;
      EXPECT_NEAR(back->view_to_clip[2][0], -0.5f, 1e-5f);
      continue;
    }
    ASSERT_FALSE(back) << note;
    EXPECT_NE(error.find(std::string("worldToNDC puts the optical axis at ") + c.where), std::string::npos) << error;
    EXPECT_NE(error.find("at or outside the display window (64 x 48 at (0, 0)"), std::string::npos) << error;
  }
}

TEST(HeaderMatrices, TransposedOrShearedMatricesAreErrors) {
  const Camera cam = posed_camera(64, 48, 50.0f);
  const ExrCameraMatrices exr = exr_matrices_from_camera(cam);
  const PixelBox box{0, 0, 63, 47};
  std::string error, note;
  ASSERT_TRUE(camera_from_exr_matrices(exr, box, box, 0, 0, &error, &note)) << error;
  ExrCameraMatrices m = exr;
  m.world_to_ndc = glm::transpose(exr.world_to_ndc);
  EXPECT_FALSE(camera_from_exr_matrices(m, box, box, 0, 0, &error, &note));
  EXPECT_NE(error.find("w depends on camera-space x or y"), std::string::npos) << error;
  m = exr;
  m.world_to_camera = glm::scale(glm::mat4(1.0f), glm::vec3(1.0f, 2.0f, 1.0f)) * exr.world_to_camera;
  EXPECT_FALSE(camera_from_exr_matrices(m, box, box, 0, 0, &error, &note));
  EXPECT_NE(error.find("scaled unequally"), std::string::npos) << error;
}

// An orthographic camera's w row says nothing of its direction: the header's NDC depth,
// growing away from the eye, does. A right-handed (-Z) orthographic camera is read as
// itself, not mirrored (its AO came out nearly inverted).
TEST(HeaderMatrices, AnOrthographicCameraLooksWhereItsDepthGrows) {
  Camera cam = posed_camera(64, 48, 50.0f);
  glm::mat4 ortho(0.0f);  // OpenGL's orthographic projection, 6.5 units wide, near 0.05, far 1000
  ortho[0][0] = 2.0f / 6.5f, ortho[1][1] = ortho[0][0] * 64.0f / 48.0f;
  ortho[2][2] = -2.0f / (1000.0f - 0.05f), ortho[3][2] = -(1000.0f + 0.05f) / (1000.0f - 0.05f), ortho[3][3] = 1.0f;
  cam.view_to_clip = ortho;
  glm::mat4 uv(1.0f);  // OpenGL NDC -> OpenEXR's (u right, v down, [0, 1])
  uv[0][0] = 0.5f, uv[3][0] = 0.5f, uv[1][1] = -0.5f, uv[3][1] = 0.5f;
  glm::mat4 plus_z(1.0f);
  plus_z[2][2] = -1.0f;
  const PixelBox box{0, 0, 63, 47};
  for (const bool minus_z : {true, false}) {
    ExrCameraMatrices m;
    m.world_to_camera = minus_z ? cam.world_to_view : plus_z * cam.world_to_view;
    m.world_to_ndc = uv * ortho * cam.world_to_view;
    std::string error, note;
    const auto back = camera_from_exr_matrices(m, box, box, 0.0f, 0.0f, &error, &note);
    ASSERT_TRUE(back) << error;
    EXPECT_FALSE(back->is_perspective());
    EXPECT_NE(note.find(minus_z ? "looks down -Z" : "looks down +Z"), std::string::npos) << note;
    expect_mat_near(back->world_to_view, cam.world_to_view, 1e-5f);
  }
}

TEST(HeaderMatrices, SingularMatricesAreErrors) {
  ExrCameraMatrices m;
  m.world_to_camera = glm::mat4(0.0f);
  const PixelBox box{0, 0, 9, 9};
  std::string error, note;
  EXPECT_FALSE(camera_from_exr_matrices(m, box, box, 0, 0, &error, &note));
  EXPECT_NE(error.find("singular"), std::string::npos) << error;
  m.world_to_camera = glm::mat4(1.0f);
  m.world_to_ndc = glm::mat4(1.0f);
  m.world_to_ndc[3][3] = 0.0f;  // w = 0 everywhere
  EXPECT_FALSE(camera_from_exr_matrices(m, box, box, 0, 0, &error, &note));
}

}  // namespace
}  // namespace ssdo::test
