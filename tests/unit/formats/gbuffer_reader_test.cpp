// read_gbuffer / inspect_gbuffer on the shared Cycles dumps, on frames written here, on the
// OpenEXR conformance files and on every kind of bad input.
#include "formats/gbuffer_reader.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/openexr.h>
#include <glm/gtc/matrix_transform.hpp>

#include "formats/camera_io.h"
#include "formats_test_util.h"

namespace ssdo::test {
namespace {

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// Largest relative error |a - b| / |b| over foreground pixels, and how many pixels exceed
// `limit`.
struct RelError {
  double max = 0;
  int64_t over = 0, checked = 0;
};
RelError compare_positions(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask, double limit) {
  RelError e;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f pa = a.at<cv::Vec3f>(y, x), pb = b.at<cv::Vec3f>(y, x);
      const double rel = cv::norm(pa - pb) / std::max(1e-12, cv::norm(pb));
      e.max = std::max(e.max, rel);
      e.over += rel > limit ? 1 : 0;
      ++e.checked;
    }
  return e;
}

// View-space positions of the foreground pixels from the read depth and camera (pixel
// centres), (0, 0, 0) elsewhere.
cv::Mat positions_from_depth(const GBuffer& g) {
  cv::Mat out(g.depth_view.size(), CV_32FC3, cv::Scalar::all(0));
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const glm::vec3 p = g.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, g.depth_view.at<float>(y, x));
      out.at<cv::Vec3f>(y, x) = cv::Vec3f(p.x, p.y, p.z);
    }
  return out;
}

// Positions from the frame's world-space Position pass, to view space with the sidecar's
// world_to_camera (read here, independently of the reader).
cv::Mat file_positions_view(const fs::path& exr, const glm::mat4& world_to_camera,
                            const std::string& prefix) {
  int w = 0, h = 0;
  const auto p = read_channels_oiio(exr, {prefix + "X", prefix + "Y", prefix + "Z"}, 0, &w, &h);
  cv::Mat out(h, w, CV_32FC3);
  for (int i = 0; i < w * h; ++i) {
    const glm::vec4 v = world_to_camera * glm::vec4(p[3 * i], p[3 * i + 1], p[3 * i + 2], 1.0f);
    out.at<cv::Vec3f>(i / w, i % w) = cv::Vec3f(v.x, v.y, v.z);
  }
  return out;
}

std::vector<fs::path> shared_frames() {
  std::vector<fs::path> frames;
  for (const auto& e : fs::directory_iterator(gbuffer_dir()))
    if (e.path().extension() == ".exr") frames.push_back(e.path());
  std::sort(frames.begin(), frames.end());
  return frames;
}

// ---------------------------------------------------------------------------------------
// The shared Cycles dumps.

TEST(SharedFrames, EveryFrameReadsAsBlenderWithSidecarCameraAndPositionsMatchDepth) {
  SSDO_SKIP_WITHOUT(gbuffer_dir());
  int frames_checked = 0;
  for (const fs::path& exr : shared_frames()) {
    SCOPED_TRACE(exr.string());
    fs::path sidecar = exr;
    sidecar.replace_extension(".camera.json");
    ReadOptions options;
    options.read_positions = true;
    const ReadResult r = read_gbuffer(exr.string(), options);
    if (!fs::exists(sidecar)) {
      // env_equirect.exr: an environment map, no G-buffer. The error names what is missing.
      ASSERT_FALSE(r.ok());
      EXPECT_TRUE(contains(r.error, exr.string())) << r.error;
      EXPECT_TRUE(contains(r.error, "depth")) << r.error;
      EXPECT_TRUE(contains(r.error, "R, G, B") || contains(r.error, "B, G, R")) << r.error;
      continue;
    }
    ASSERT_TRUE(r.ok()) << r.error;
    const nlohmann::json side = read_json(sidecar);
    const GBuffer& g = r.gbuffer;
    EXPECT_EQ(r.info.profile, "blender");
    EXPECT_EQ(r.info.layer, "ViewLayer");
    EXPECT_EQ(r.info.camera_source, "sidecar " + sidecar.string());
    EXPECT_EQ(r.info.depth_kind, "planar");
    EXPECT_FALSE(r.info.normals_reconstructed);
    EXPECT_EQ(g.width_px(), side["width"].get<int>());
    EXPECT_EQ(g.height_px(), side["height"].get<int>());
    EXPECT_NEAR(g.camera.fov_x_deg(), side["fov_x_deg"].get<double>(), 1e-3);
    EXPECT_NEAR(g.camera.fov_y_deg(), side["fov_y_deg"].get<double>(), 1e-3);
    ASSERT_TRUE(r.info.ao_distance_world.has_value());
    EXPECT_FLOAT_EQ(*r.info.ao_distance_world, 1.0f);

    // Background (depth 1e10) is masked, never geometry; the counts add up.
    const int64_t background = side["verification"]["background_pixels"].get<int64_t>();
    EXPECT_EQ(r.info.foreground_pixels + r.info.masked_pixels, int64_t(g.width_px()) * g.height_px());
    EXPECT_EQ(r.info.foreground_pixels, cv::countNonZero(g.mask));
    // Masked: exactly the pixels with background depth (1e10; anything beyond clip_far would
    // be masked too, there is none). The sidecar's own count differs by a few pixels.
    const auto raw_depth = read_channels_oiio(exr, {"ViewLayer.Depth.Z"});
    const float clip_far = side["clip_far"].get<float>();
    int64_t beyond_far = 0, exactly_background = 0;
    for (float d : raw_depth) {
      beyond_far += d > clip_far ? 1 : 0;
      exactly_background += d == 1e10f ? 1 : 0;
    }
    EXPECT_EQ(r.info.masked_pixels, exactly_background);
    EXPECT_EQ(r.info.masked_pixels, beyond_far);
    EXPECT_NEAR(double(r.info.masked_pixels), double(background), raw_depth.size() / 1000.0);
    EXPECT_EQ(r.info.nonfinite_pixels, 0);
    const auto range = side["verification"]["depth_range_valid"];
    EXPECT_NEAR(r.info.depth_min_view, range[0].get<float>(), 1e-4);
    EXPECT_NEAR(r.info.depth_max_view, range[1].get<float>(), 1e-4);

    // Acceptance: view positions from depth + camera equal the Position pass in view space
    // (sidecar world_to_camera) within 1e-3 relative on every foreground pixel.
    const cv::Mat from_depth = positions_from_depth(g);
    const cv::Mat from_file =
        file_positions_view(exr, json_matrix(side["world_to_camera"]), "ViewLayer.Position.");
    const RelError e = compare_positions(from_depth, from_file, g.mask, 1e-3);
    EXPECT_GT(e.checked, 1000);
    EXPECT_EQ(e.over, 0) << "max relative error " << e.max;
    // The reader's own conversion of the Position pass agrees too.
    const RelError e2 = compare_positions(g.position_view, from_file, g.mask, 1e-5);
    EXPECT_EQ(e2.over, 0) << "max relative error " << e2.max;

    // Normals: unit, facing the camera, zero on the background.
    int64_t bad_normals = 0;
    for (int y = 0; y < g.height_px(); ++y)
      for (int x = 0; x < g.width_px(); ++x) {
        const cv::Vec3f n = g.normal_view.at<cv::Vec3f>(y, x);
        if (!g.mask.at<uint8_t>(y, x)) {
          bad_normals += cv::norm(n) != 0.0 ? 1 : 0;
          continue;
        }
        const cv::Vec3f p = from_depth.at<cv::Vec3f>(y, x);
        bad_normals += std::abs(cv::norm(n) - 1.0) > 1e-4 || n.dot(p) > 0.0f ? 1 : 0;
        EXPECT_TRUE(std::isinf(g.depth_view.at<float>(y, x)) == false);
      }
    EXPECT_EQ(bad_normals, 0);
    ++frames_checked;
  }
  EXPECT_GE(frames_checked, 4);
}

TEST(SharedFrames, LightingIsAlbedoTimesDirectAndReferencesAreRead) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.exr");
  const fs::path exr = gbuffer_dir() / "cornell.exr";
  const ReadResult r = read_gbuffer(exr.string());
  ASSERT_TRUE(r.ok()) << r.error;
  const GBuffer& g = r.gbuffer;
  ASSERT_EQ(g.albedo.type(), CV_32FC3);
  ASSERT_EQ(g.lighting.type(), CV_32FC3);
  ASSERT_EQ(g.references.count("AO"), 1u);
  ASSERT_EQ(g.references.count("DiffDir"), 1u);
  ASSERT_EQ(g.references.count("DiffInd"), 1u);
  EXPECT_EQ(g.references.at("AO").type(), CV_32FC1);
  EXPECT_EQ(g.references.at("DiffInd").type(), CV_32FC3);
  const auto col = read_channels_oiio(exr, {"ViewLayer.DiffCol.R", "ViewLayer.DiffCol.G", "ViewLayer.DiffCol.B"});
  const auto dir = read_channels_oiio(exr, {"ViewLayer.DiffDir.R", "ViewLayer.DiffDir.G", "ViewLayer.DiffDir.B"});
  const auto ao = read_channels_oiio(exr, {"ViewLayer.AO.R"});
  for (int i : {0, 1000, 640 * 180 + 320, 640 * 300 + 100}) {
    const int y = i / 640, x = i % 640;
    for (int c = 0; c < 3; ++c) {
      EXPECT_FLOAT_EQ(g.albedo.at<cv::Vec3f>(y, x)[c], col[3 * i + c]);
      EXPECT_FLOAT_EQ(g.references.at("DiffDir").at<cv::Vec3f>(y, x)[c], dir[3 * i + c]);
      EXPECT_FLOAT_EQ(g.lighting.at<cv::Vec3f>(y, x)[c], col[3 * i + c] * dir[3 * i + c]);
    }
    EXPECT_FLOAT_EQ(g.references.at("AO").at<float>(y, x), ao[i]);
  }
  bool lighting_listed = false;
  for (const auto& u : r.info.uses) lighting_listed |= u.input == "lighting";
  EXPECT_TRUE(lighting_listed);
}

TEST(SharedFrames, DepthOnlyReadsDepthMaskAndCameraAndNothingElse) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.exr");
  const std::string exr = (gbuffer_dir() / "cornell.exr").string();
  const ReadResult whole = read_gbuffer(exr);
  const ReadResult depth = read_gbuffer(exr, depth_only(ReadOptions{}));
  ASSERT_TRUE(whole.ok() && depth.ok()) << whole.error << depth.error;
  const GBuffer& g = depth.gbuffer;
  EXPECT_TRUE(g.normal_view.empty() && g.albedo.empty() && g.lighting.empty() && g.position_view.empty());
  EXPECT_TRUE(g.references.empty());
  EXPECT_EQ(cv::norm(g.mask, whole.gbuffer.mask, cv::NORM_INF), 0.0);
  cv::Mat fg_depth, fg_whole;
  g.depth_view.copyTo(fg_depth, g.mask);
  whole.gbuffer.depth_view.copyTo(fg_whole, g.mask);
  EXPECT_EQ(cv::norm(fg_depth, fg_whole, cv::NORM_INF), 0.0);
  EXPECT_EQ(g.camera.world_to_view, whole.gbuffer.camera.world_to_view);
  ASSERT_EQ(depth.info.uses.size(), 1u);
  EXPECT_EQ(depth.info.uses[0].input, "depth");
}

TEST(SharedFrames, InspectReadsTheHeaderOnly) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "greeble.exr");
  const ReadResult r = inspect_gbuffer((gbuffer_dir() / "greeble.exr").string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.gbuffer.depth_view.empty());
  EXPECT_EQ(r.info.width_px, 640);
  EXPECT_EQ(r.info.height_px, 360);
  EXPECT_EQ(r.info.profile, "blender");
  EXPECT_EQ(r.info.channels.size(), 26u);
  EXPECT_TRUE(contains(r.info.channels[0], "(half)")) << r.info.channels[0];
  EXPECT_NEAR(r.info.fov_x_deg, 50.0, 1e-3);
  EXPECT_EQ(r.gbuffer.camera.width_px, 640);
  ASSERT_FALSE(r.info.uses.empty());
  EXPECT_EQ(r.info.uses[0].input, "depth");
  EXPECT_EQ(r.info.uses[0].channels, "ViewLayer.Depth.Z");
  EXPECT_EQ(r.info.uses[1].channels, "ViewLayer.Normal.{X,Y,Z}");
  EXPECT_EQ(r.info.uses[1].space, "world");
}

// ---------------------------------------------------------------------------------------
// Camera from worldToCamera / worldToNDC header attributes only.

// Rewrites a shared frame as generic channels Z + P.{X,Y,Z} (world) with the camera only in
// the header. camera_looks_down_plus_z: OpenEXR/RenderMan convention (left-handed camera
// space) or the right-handed -Z convention Blender- and Arnold-style writers use.
void check_header_camera_frame(const std::string& scene, bool camera_looks_down_plus_z) {
  const fs::path exr = gbuffer_dir() / (scene + ".exr");
  fs::path sidecar = exr;
  sidecar.replace_extension(".camera.json");
  const nlohmann::json side = read_json(sidecar);
  const glm::mat4 world_to_camera = json_matrix(side["world_to_camera"]);
  const glm::mat4 projection = json_matrix(side["projection"]);
  int w = 0, h = 0;
  const auto depth = read_channels_oiio(exr, {"ViewLayer.Depth.Z"}, 0, &w, &h);
  const auto pos = read_channels_oiio(exr, {"ViewLayer.Position.X", "ViewLayer.Position.Y", "ViewLayer.Position.Z"});
  TestExr t;
  t.width = w;
  t.height = h;
  t.channels = {{"Z", OIIO::TypeDesc::FLOAT, depth},
                {"P.X", OIIO::TypeDesc::FLOAT, {}},
                {"P.Y", OIIO::TypeDesc::FLOAT, {}},
                {"P.Z", OIIO::TypeDesc::FLOAT, {}}};
  for (int i = 0; i < w * h; ++i)
    for (int c = 0; c < 3; ++c) t.channels[1 + c].values.push_back(pos[3 * i + c]);
  // OpenGL NDC -> OpenEXR NDC (u right, v down, [0, 1] over the display window).
  glm::mat4 uv_from_gl(1.0f);
  uv_from_gl[0][0] = 0.5f;
  uv_from_gl[3][0] = 0.5f;
  uv_from_gl[1][1] = -0.5f;
  uv_from_gl[3][1] = 0.5f;
  glm::mat4 to_exr_camera(1.0f);
  if (camera_looks_down_plus_z) to_exr_camera[2][2] = -1.0f;
  t.matrices = {{"worldToCamera", to_exr_camera * world_to_camera},
                {"worldToNDC", uv_from_gl * projection * world_to_camera}};
  ScratchDir dir;
  const fs::path path = dir / (scene + "_header_camera.exr");
  std::string error;
  ASSERT_TRUE(t.write(path, &error)) << error;

  ReadOptions options;
  options.read_positions = true;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.profile, "generic");
  EXPECT_EQ(r.info.camera_source, "header worldToCamera/worldToNDC");
  ASSERT_FALSE(r.info.notes.empty());
  EXPECT_TRUE(contains(r.info.notes[0], camera_looks_down_plus_z ? "+Z" : "-Z")) << r.info.notes[0];
  const Camera& cam = r.gbuffer.camera;
  for (int c = 0; c < 4; ++c)
    for (int row : {0, 1, 3})
      EXPECT_NEAR(cam.view_to_clip[c][row], projection[c][row], 1e-4) << c << "," << row;
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row)
      EXPECT_NEAR(cam.world_to_view[c][row], world_to_camera[c][row], 1e-5);

  const cv::Mat from_depth = positions_from_depth(r.gbuffer);
  const cv::Mat from_file = file_positions_view(path, world_to_camera, "P.");
  const RelError e = compare_positions(from_depth, from_file, r.gbuffer.mask, 1e-3);
  EXPECT_GT(e.checked, 1000);
  EXPECT_EQ(e.over, 0) << "max relative error " << e.max;
  // Generic P is world space under a header camera (stated in info) and converted.
  const RelError e2 = compare_positions(r.gbuffer.position_view, from_file, r.gbuffer.mask, 1e-5);
  EXPECT_EQ(e2.over, 0) << "max relative error " << e2.max;
}

TEST(HeaderCamera, OpenExrConventionCameraLooksDownPlusZ) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.exr");
  check_header_camera_frame("cornell", true);
}

TEST(HeaderCamera, RightHandedCameraLooksDownMinusZ) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "depthgap.exr");
  check_header_camera_frame("depthgap", false);
}

// ---------------------------------------------------------------------------------------
// Small frames written here.

TestExr generic_frame(int w, int h, float depth) {
  TestExr t;
  t.width = w;
  t.height = h;
  t.channels = {{"Z", OIIO::TypeDesc::FLOAT, std::vector<float>(size_t(w) * h, depth)}};
  return t;
}

// Generic N.X, N.Y, N.Z channels holding one normal on every pixel of t.
void add_constant_normals(TestExr& t, const glm::vec3& n) {
  const size_t pixels = size_t(t.width) * size_t(t.height);
  t.channels.push_back({"N.X", OIIO::TypeDesc::FLOAT, std::vector<float>(pixels, n.x)});
  t.channels.push_back({"N.Y", OIIO::TypeDesc::FLOAT, std::vector<float>(pixels, n.y)});
  t.channels.push_back({"N.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(pixels, n.z)});
}

// A frame of constant planar depth written with OpenEXR, with the given matrix attributes
// stored as M44d (OpenImageIO writes worldToCamera and worldToNDC only as M44f).
void write_frame_with_double_matrices(const fs::path& path, int width, int height, float depth,
                                      const std::vector<std::pair<std::string, glm::dmat4>>& matrices) {
  const Imath::Box2i window(Imath::V2i(0, 0), Imath::V2i(width - 1, height - 1));
  Imf::Header header(window, window);
  for (const auto& [name, m] : matrices) {
    Imath::M44d value;
    std::copy(&m[0][0], &m[0][0] + 16, &value.x[0][0]);  // column-vector glm = row-vector Imath
    header.insert(name, Imf::M44dAttribute(value));
  }
  header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
  std::vector<float> z(size_t(width) * height, depth);
  Imf::FrameBuffer fb;
  fb.insert("Z", Imf::Slice::Make(Imf::FLOAT, z.data(), window, 4, 4 * size_t(width)));
  Imf::OutputFile out(path.c_str(), header);
  out.setFrameBuffer(fb);
  out.writePixels(height);
}

// worldToCamera / worldToNDC stored as double matrices (M44d) are the same camera as
// stored as float ones (M44f), which OpenEXR's hasWorldToCamera alone would see.
TEST(HeaderCamera, DoubleMatricesAreRead) {
  ScratchDir dir;
  Camera cam = Camera::from_fov_x(16, 8, 60.0f, 0.1f, 100.0f);
  cam.world_to_view = glm::translate(glm::mat4(1.0f), glm::vec3(0.5f, -1.0f, -2.0f)) *
                      glm::rotate(glm::mat4(1.0f), 0.3f, glm::vec3(0.0f, 1.0f, 0.0f));
  cam.view_to_world = glm::inverse(cam.world_to_view);
  const ExrCameraMatrices m = exr_matrices_from_camera(cam);
  TestExr as_float = generic_frame(16, 8, 3.0f);
  as_float.matrices = {{"worldToCamera", m.world_to_camera}, {"worldToNDC", m.world_to_ndc}};
  ASSERT_TRUE(as_float.write(dir / "m44f.exr"));
  write_frame_with_double_matrices(dir / "m44d.exr", 16, 8, 3.0f,
                                   {{"worldToCamera", glm::dmat4(m.world_to_camera)},
                                    {"worldToNDC", glm::dmat4(m.world_to_ndc)}});
  const ReadResult f = read_gbuffer((dir / "m44f.exr").string());
  const ReadResult d = read_gbuffer((dir / "m44d.exr").string());
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_TRUE(d.ok()) << d.error;
  EXPECT_EQ(d.info.camera_source, "header worldToCamera/worldToNDC");
  EXPECT_NEAR(d.info.fov_x_deg, 60.0, 1e-3);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) {
      EXPECT_EQ(d.gbuffer.camera.world_to_view[c][r], f.gbuffer.camera.world_to_view[c][r]);
      EXPECT_EQ(d.gbuffer.camera.view_to_clip[c][r], f.gbuffer.camera.view_to_clip[c][r]);
      EXPECT_NEAR(d.gbuffer.camera.world_to_view[c][r], cam.world_to_view[c][r], 1e-5);
    }
}

// A header with worldToCamera but no worldToNDC (float or double) has no camera: the
// error says what is missing, not the generic request for the attributes it has. With
// --fov the frame is read, with a note that the pose is not used.
TEST(HeaderCamera, PoseWithoutProjectionSaysWhatIsMissing) {
  ScratchDir dir;
  const glm::mat4 pose = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 0.0f, -3.0f));
  for (const bool as_double : {false, true}) {
    SCOPED_TRACE(as_double);
    const fs::path path = dir / "pose_only.exr";
    if (as_double) {
      write_frame_with_double_matrices(path, 16, 8, 3.0f, {{"worldToCamera", glm::dmat4(pose)}});
    } else {
      TestExr t = generic_frame(16, 8, 3.0f);
      t.matrices = {{"worldToCamera", pose}};
      ASSERT_TRUE(t.write(path));
    }
    const ReadResult r = read_gbuffer(path.string());
    ASSERT_FALSE(r.ok());
    EXPECT_TRUE(contains(r.error, "no camera: the header has worldToCamera (the pose) but no worldToNDC (the projection)"))
        << r.error;
    EXPECT_TRUE(contains(r.error, "pose_only.camera.json")) << r.error;
    EXPECT_TRUE(contains(r.error, "--fov DEGREES")) << r.error;
    EXPECT_FALSE(contains(r.error, "store worldToCamera and worldToNDC")) << r.error;
    ReadOptions options;
    options.fov_x_deg = 50.0f;
    const ReadResult fov = read_gbuffer(path.string(), options);
    ASSERT_TRUE(fov.ok()) << fov.error;
    EXPECT_EQ(fov.info.camera_source, "--fov 50");
    bool noted = false;
    for (const std::string& n : fov.info.notes) noted |= contains(n, "no worldToNDC (the projection): it is not used");
    EXPECT_TRUE(noted);
  }
  write_frame_with_double_matrices(dir / "ndc_only.exr", 16, 8, 3.0f, {{"worldToNDC", glm::dmat4(1.0)}});
  const ReadResult r = read_gbuffer((dir / "ndc_only.exr").string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "the header has worldToNDC (the projection) but no worldToCamera (the pose)")) << r.error;
}

// A header worldToNDC in the [-1, 1] convention is read as the camera it means, with a
// note; one whose optical axis lands elsewhere outside the picture is refused, naming the
// attribute and what reads the frame instead, and with --fov that camera is used, with a
// warning.
TEST(HeaderCamera, NdcOfAnotherConventionIsConvertedOrRefused) {
  ScratchDir dir;
  const Camera cam = Camera::from_fov_x(32, 16, 60.0f, 0.1f, 100.0f);
  TestExr gl = generic_frame(32, 16, 3.0f);
  gl.matrices = {{"worldToCamera", glm::mat4(1.0f)}, {"worldToNDC", cam.view_to_clip}};
  ASSERT_TRUE(gl.write(dir / "gl.exr"));
  const ReadResult converted = read_gbuffer((dir / "gl.exr").string());
  ASSERT_TRUE(converted.ok()) << converted.error;
  EXPECT_NEAR(converted.info.fov_x_deg, 60.0, 1e-3);
  EXPECT_NEAR(converted.gbuffer.camera.view_to_clip[2][0], 0.0f, 1e-6f);  // no lens shift
  EXPECT_TRUE(contains(converted.info.notes.front(), "worldToNDC is in the [-1, 1] convention"))
      << converted.info.notes.front();

  glm::mat4 shifted = cam.view_to_clip;
  shifted[2][1] = -0.5f;  // the axis at OpenGL NDC y = 0.5: outside OpenEXR's [0, 1]
  gl.matrices = {{"worldToCamera", glm::mat4(1.0f)}, {"worldToNDC", shifted}};
  const fs::path path = dir / "shifted.exr";
  ASSERT_TRUE(gl.write(path));
  const ReadResult refused = read_gbuffer(path.string());
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(contains(refused.error, "worldToNDC puts the optical axis at NDC (0, 0.5), pixel (0, 8)")) << refused.error;
  EXPECT_TRUE(contains(refused.error, "a camera sidecar (" + (dir / "shifted.camera.json").string() +
                                          ") or --fov DEGREES reads the frame"))
      << refused.error;
  ReadOptions options;
  options.fov_x_deg = 45.0f;
  const ReadResult fov = read_gbuffer(path.string(), options);
  ASSERT_TRUE(fov.ok()) << fov.error;
  EXPECT_EQ(fov.info.camera_source, "--fov 45");
  EXPECT_NEAR(fov.info.fov_x_deg, 45.0, 1e-3);
  ASSERT_FALSE(fov.info.notes.empty());
  EXPECT_EQ(fov.info.notes.front().rfind(kWarningNote, 0), 0u) << fov.info.notes.front();
  EXPECT_TRUE(contains(fov.info.notes.front(), "optical axis at NDC (0, 0.5)")) << fov.info.notes.front();
  EXPECT_TRUE(contains(fov.info.notes.front(), "--fov gives the camera instead")) << fov.info.notes.front();
}

// Clip distances written as whole numbers (int attributes, as oiiotool's --attrib writes
// clipFar 5) are read as the float ones are, not dropped.
TEST(HeaderCamera, IntegerClipDistancesAreRead) {
  ScratchDir dir;
  TestExr t = generic_frame(16, 8, 3.0f);
  const Camera cam = Camera::from_fov_x(16, 8, 60.0f, 0.1f, 100.0f);
  glm::mat4 uv_from_gl(1.0f);
  uv_from_gl[0][0] = 0.5f, uv_from_gl[3][0] = 0.5f, uv_from_gl[1][1] = -0.5f, uv_from_gl[3][1] = 0.5f;
  t.matrices = {{"worldToCamera", glm::mat4(1.0f)}, {"worldToNDC", uv_from_gl * cam.view_to_clip}};
  t.int_attributes = {{"clipNear", 1}, {"clipFar", 5}};
  const fs::path path = dir / "int_clip.exr";
  ASSERT_TRUE(t.write(path));
  const ReadResult r = read_gbuffer(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.camera_source, "header worldToCamera/worldToNDC");
  EXPECT_FLOAT_EQ(r.gbuffer.camera.near_view, 1.0f);
  EXPECT_FLOAT_EQ(r.gbuffer.camera.far_view, 5.0f);
}

TEST(ReadErrors, MissingFile) {
  const ReadResult r = read_gbuffer("/nonexistent/folder/frame.exr");
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "/nonexistent/folder/frame.exr")) << r.error;
  EXPECT_TRUE(contains(r.error, "no such file")) << r.error;
}

TEST(ReadErrors, TextFileIsNotAnExr) {
  ScratchDir dir;
  const fs::path path = dir / "notes.exr";
  std::ofstream(path) << "this is not an image\n";
  const ReadResult r = read_gbuffer(path.string(), {});
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, path.string())) << r.error;
  EXPECT_TRUE(contains(r.error, "not an OpenEXR file")) << r.error;
}

TEST(ReadErrors, TruncatedExr) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.exr");
  ScratchDir dir;
  std::ifstream in(gbuffer_dir() / "cornell.exr", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Inside the header, inside the offset table, and halfway through the pixel data.
  for (size_t n : {size_t(200), size_t(1500), bytes.size() / 2}) {
    SCOPED_TRACE(n);
    const fs::path path = dir / ("cornell_" + std::to_string(n) + ".exr");
    fs::copy_file(gbuffer_dir() / "cornell.camera.json",
                  dir / ("cornell_" + std::to_string(n) + ".camera.json"));
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(n));
    const ReadResult r = read_gbuffer(path.string());
    ASSERT_FALSE(r.ok());
    EXPECT_TRUE(contains(r.error, path.string())) << r.error;
    EXPECT_TRUE(contains(r.error, "truncated")) << r.error;
  }
}

TEST(ReadErrors, MissingDepthChannelIsNamedAndPresentChannelsListed) {
  ScratchDir dir;
  TestExr t;
  t.width = t.height = 4;
  for (const char* c : {"R", "G", "B"}) t.channels.push_back({c, OIIO::TypeDesc::HALF, std::vector<float>(16, 0.5f)});
  const fs::path path = dir / "rgb.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, path.string())) << r.error;
  EXPECT_TRUE(contains(r.error, "depth")) << r.error;
  EXPECT_TRUE(contains(r.error, "Depth.Z")) << r.error;
  EXPECT_TRUE(contains(r.error, "channels present: B, G, R")) << r.error;
}

TEST(ReadErrors, MissingMappedChannelIsNamed) {
  ScratchDir dir;
  const fs::path path = dir / "z.exr";
  ASSERT_TRUE(generic_frame(4, 4, 2.0f).write(path));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  options.mapping.normal = "Nrm";
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "\"Nrm\"")) << r.error;
  EXPECT_TRUE(contains(r.error, "channels present: Z")) << r.error;
}

TEST(ReadErrors, NoCameraNamesTheThreeWays) {
  ScratchDir dir;
  const fs::path path = dir / "nocam.exr";
  ASSERT_TRUE(generic_frame(8, 4, 2.0f).write(path));
  const ReadResult r = read_gbuffer(path.string(), {});
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, path.string())) << r.error;
  EXPECT_TRUE(contains(r.error, "nocam.camera.json")) << r.error;
  EXPECT_TRUE(contains(r.error, "worldToCamera and worldToNDC")) << r.error;
  EXPECT_TRUE(contains(r.error, "--fov")) << r.error;
  // Header-only inspection reports the same.
  EXPECT_FALSE(inspect_gbuffer(path.string(), {}).ok());
}

TEST(ReadErrors, ExplicitSidecarThatDoesNotExist) {
  ScratchDir dir;
  const fs::path path = dir / "frame.exr";
  ASSERT_TRUE(generic_frame(8, 4, 2.0f).write(path));
  ReadOptions options;
  options.camera_json = (dir / "missing.camera.json").string();
  options.fov_x_deg = 60.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "missing.camera.json")) << r.error;
}

TEST(ReadErrors, SidecarOfAnotherResolution) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.camera.json");
  ScratchDir dir;
  const fs::path path = dir / "small.exr";
  ASSERT_TRUE(generic_frame(8, 4, 2.0f).write(path));
  ReadOptions options;
  options.camera_json = (gbuffer_dir() / "cornell.camera.json").string();
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "640x360")) << r.error;
}

TEST(ReadErrors, AbsurdDimensionsRefusedBeforeAllocating) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.exr");
  ReadOptions options;
  options.max_pixels = 640 * 360 - 1;
  const ReadResult r = read_gbuffer((gbuffer_dir() / "cornell.exr").string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "refused")) << r.error;
  EXPECT_TRUE(contains(r.error, "640x360")) << r.error;
}

TEST(ReadErrors, HugeDataWindowInHeaderRefused) {
  // A valid 4x4 file whose dataWindow attribute is patched to 200000 x 200000 pixels: the
  // header is all the reader looks at before refusing.
  ScratchDir dir;
  const fs::path path = dir / "huge.exr";
  TestExr t = generic_frame(4, 4, 2.0f);
  t.compression = "none";
  ASSERT_TRUE(t.write(path));
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::string key = std::string("dataWindow") + '\0' + "box2i" + '\0';
  const size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos);
  const int32_t box[4] = {0, 0, 199999, 199999};
  f.seekp(std::streamoff(at + key.size() + 4));  // after the 4-byte attribute size
  f.write(reinterpret_cast<const char*>(box), sizeof box);
  f.close();
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, path.string())) << r.error;
  EXPECT_TRUE(contains(r.error, "refused") || contains(r.error, "truncated")) << r.error;
}

TEST(ReadErrors, UnknownPartIsNamedWithTheParts) {
  const fs::path mp = conformance_dir() / "valid" / "Beachball" / "multipart.0001.exr";
  SSDO_SKIP_WITHOUT(mp);
  ReadOptions options;
  options.part = "depth_centre";
  options.fov_x_deg = 40.0f;
  const ReadResult r = read_gbuffer(mp.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "depth_centre")) << r.error;
  EXPECT_TRUE(contains(r.error, "\"depth_left\"")) << r.error;
}

TEST(ReadErrors, ChannelsFromPartsOfDifferentSizes) {
  const fs::path mp = conformance_dir() / "valid" / "Beachball" / "multipart.0001.exr";
  SSDO_SKIP_WITHOUT(mp);
  ReadOptions options;
  options.part = "depth_left";  // 877 x 876 at (688, 245)
  options.fov_x_deg = 40.0f;
  options.mapping.depth_back = "whitebarmask.mask";  // whitebarmask_left: 385 x 769
  const ReadResult r = read_gbuffer(mp.string(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error, "parts of different sizes")) << r.error;
  EXPECT_TRUE(contains(r.error, "whitebarmask_left")) << r.error;
  // A reference pass there is only left out, with a note: the terms do not need it.
  options.mapping.depth_back.clear();
  options.mapping.references["mask"] = "whitebarmask.mask";
  const ReadResult with_reference = read_gbuffer(mp.string(), options);
  ASSERT_TRUE(with_reference.ok()) << with_reference.error;
  EXPECT_EQ(with_reference.gbuffer.references.count("mask"), 0u);
  bool noted = false;
  for (const std::string& n : with_reference.info.notes)
    noted |= contains(n, "reference:mask left out: its part \"whitebarmask_left\"");
  EXPECT_TRUE(noted);
}

// Inputs a profile finds in a part of another size (a multi-part file whose normals and
// albedo were rendered over a smaller region) are left out with a note, as a frame without
// them is read; named with --map, they are an error.
TEST(ReadErrors, FoundInputsInAPartOfAnotherSizeAreLeftOut) {
  ScratchDir dir;
  TestExr depth = generic_frame(8, 4, 3.0f);
  depth.part_name = "depth";
  TestExr shading = generic_frame(4, 4, 3.0f);
  shading.channels.clear();
  shading.part_name = "shading";
  shading.display_width = 8;  // the parts of a file share one display window
  shading.display_height = 4;
  add_constant_normals(shading, glm::vec3(0, 0, 1));
  for (const char* c : {"albedo.R", "albedo.G", "albedo.B"})
    shading.channels.push_back({c, OIIO::TypeDesc::HALF, std::vector<float>(16, 0.5f)});
  const fs::path path = dir / "parts.exr";
  std::string error;
  ASSERT_TRUE(write_parts(path, {depth, shading}, &error)) << error;
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  options.read_albedo = true;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.info.normals_reconstructed);
  EXPECT_TRUE(r.gbuffer.albedo.empty());
  for (const char* input : {"normal", "albedo"}) {
    bool noted = false;
    for (const std::string& n : r.info.notes)
      noted |= n.rfind(std::string(input) + " left out: its part \"shading\" has data window", 0) == 0;
    EXPECT_TRUE(noted) << input;
  }
  options.mapping.normal = "N";
  const ReadResult mapped = read_gbuffer(path.string(), options);
  ASSERT_FALSE(mapped.ok());
  EXPECT_TRUE(contains(mapped.error, "parts of different sizes: normal channels in part \"shading\"")) << mapped.error;
}

TEST(ReadConversions, NanAndInfInDepthAndNormalsAreMaskedAndCounted) {
  ScratchDir dir;
  const int w = 8, h = 4;
  TestExr t = generic_frame(w, h, 3.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto& z = t.channels[0].values;
  z[1] = nan;
  z[2] = inf;
  z[3] = -inf;
  z[4] = 1e10f;  // background
  z[5] = 0.0f;   // background
  z[6] = -2.0f;  // background
  for (const char* c : {"N.X", "N.Y", "N.Z"}) t.channels.push_back({c, OIIO::TypeDesc::HALF, std::vector<float>(w * h, 0.0f)});
  for (int i = 0; i < w * h; ++i) t.channels[3].values[i] = 1.0f;  // N.Z = +1, facing the camera
  t.channels[1].values[10] = nan;  // N.X
  t.channels[2].values[11] = inf;  // N.Y
  t.channels[3].values[12] = 0.0f;  // zero normal: reported missing, not masked
  const fs::path path = dir / "nonfinite.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  const GBuffer& g = r.gbuffer;
  EXPECT_EQ(r.info.nonfinite_pixels, 5);
  EXPECT_EQ(r.info.masked_pixels, 8);
  EXPECT_EQ(r.info.foreground_pixels, w * h - 8);
  EXPECT_EQ(r.info.repaired_normal_pixels, 1);
  for (int i : {1, 2, 3, 4, 5, 6, 10, 11}) {
    SCOPED_TRACE(i);
    EXPECT_EQ(g.mask.at<uint8_t>(i / w, i % w), 0);
    EXPECT_TRUE(std::isinf(g.depth_view.at<float>(i / w, i % w)));
    EXPECT_EQ(g.normal_view.at<cv::Vec3f>(i / w, i % w), cv::Vec3f(0, 0, 0));
  }
  // Under a --fov camera generic N is view space; (0, 0, 1) faces the camera everywhere.
  EXPECT_EQ(g.normal_view.at<cv::Vec3f>(3, 7), cv::Vec3f(0, 0, 1));
  // The zero normal stays (0, 0, 0), marked for reconstruction (service/frame_inputs.h).
  EXPECT_EQ(g.mask.at<uint8_t>(12 / w, 12 % w), 255);
  EXPECT_EQ(g.normal_view.at<cv::Vec3f>(12 / w, 12 % w), cv::Vec3f(0, 0, 0));
  ASSERT_EQ(g.normal_missing.type(), CV_8UC1);
  EXPECT_EQ(g.normal_missing.at<uint8_t>(12 / w, 12 % w), 1);
  EXPECT_EQ(cv::countNonZero(g.normal_missing), 1);
  EXPECT_TRUE(r.info.notes.empty() || !contains(r.info.notes.back(), "zero normal"));
  EXPECT_FLOAT_EQ(r.info.depth_min_view, 3.0f);
  EXPECT_FLOAT_EQ(r.info.depth_max_view, 3.0f);
  EXPECT_EQ(r.info.uses[1].space, "view");
}

// The kernels multiply with albedo and lighting: a non-finite sample there becomes 0, and
// so does a lighting product that overflows; every other sample is kept as stored.
TEST(ReadConversions, NanInfAndNegativeAlbedoAndLightingBecomeZero) {
  ScratchDir dir;
  const int w = 8, h = 4, n = w * h;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  TestExr t;
  t.width = w;
  t.height = h;
  t.channels.push_back({"ViewLayer.Depth.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(n, 3.0f)});
  std::vector<float> col(3 * size_t(n)), light(3 * size_t(n));
  for (int i = 0; i < 3 * n; ++i) col[i] = 0.1f + 0.01f * float(i), light[i] = 2.0f + 0.5f * float(i);
  col[0] = nan, col[4] = inf, col[8] = -inf;      // albedo itself non-finite
  light[12] = nan, light[16] = -inf;               // the direct pass non-finite
  col[20] = 1e30f, light[20] = 1e30f;              // a finite product that overflows
  col[24] = -0.5f, light[28] = -5.0f;              // negative albedo, negative direct light
  col[32] = -0.5f, light[32] = -5.0f;              // both negative: no positive product
  const char* rgb = "RGB";
  for (int c = 0; c < 3; ++c) {
    std::vector<float> a(n), l(n);
    for (int i = 0; i < n; ++i) a[i] = col[3 * i + c], l[i] = light[3 * i + c];
    t.channels.push_back({std::string("ViewLayer.DiffCol.") + rgb[c], OIIO::TypeDesc::FLOAT, a});
    t.channels.push_back({std::string("ViewLayer.DiffDir.") + rgb[c], OIIO::TypeDesc::FLOAT, l});
  }
  const fs::path path = dir / "nonfinite_light.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    options.threads = threads;
    const ReadResult r = read_gbuffer(path.string(), options);
    ASSERT_TRUE(r.ok()) << r.error;
    const GBuffer& g = r.gbuffer;
    ASSERT_EQ(g.albedo.type(), CV_32FC3);
    ASSERT_EQ(g.lighting.type(), CV_32FC3);
    for (int i = 0; i < 3 * n; ++i) {
      SCOPED_TRACE(i);
      const int pixel = i / 3, c = i % 3;
      const float albedo = g.albedo.at<cv::Vec3f>(pixel / w, pixel % w)[c];
      const float lighting = g.lighting.at<cv::Vec3f>(pixel / w, pixel % w)[c];
      const bool albedo_usable = std::isfinite(col[i]) && col[i] >= 0.0f;
      EXPECT_EQ(albedo, albedo_usable ? col[i] : 0.0f);
      const float product = (albedo_usable ? col[i] : 0.0f) * light[i];
      EXPECT_EQ(lighting, std::isfinite(product) && product >= 0.0f ? product : 0.0f);
      EXPECT_GE(lighting, 0.0f);
    }
    // The direct pass as a reference keeps what the renderer wrote.
    EXPECT_TRUE(std::isnan(g.references.at("DiffDir").at<cv::Vec3f>(0, 4)[0]));  // light[12]
  }
}

TEST(ReadConversions, ConformanceNanInfImageIsMaskedAndCounted) {
  // BrightRingsNanInf.exr: half RGB with NaN and Inf samples; R serves as depth here.
  const fs::path path = conformance_dir() / "valid" / "TestImages" / "BrightRingsNanInf.exr";
  SSDO_SKIP_WITHOUT(path);
  ReadOptions options;
  options.fov_x_deg = 40.0f;
  options.mapping.depth = "R";
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  const auto red = read_channels_oiio(path, {"R"});
  int64_t nonfinite = 0, background = 0;
  for (float v : red) {
    nonfinite += std::isfinite(v) ? 0 : 1;
    background += std::isfinite(v) && !(v > 0.0f && v < 1e9f) ? 1 : 0;
  }
  ASSERT_GT(nonfinite, 0);
  EXPECT_EQ(r.info.nonfinite_pixels, nonfinite);
  EXPECT_EQ(r.info.masked_pixels, nonfinite + background);
  // No normals in the file: none read, reported for reconstruction.
  EXPECT_TRUE(r.gbuffer.normal_view.empty());
  EXPECT_TRUE(r.info.normals_reconstructed);
  for (int y = 0; y < r.gbuffer.height_px(); ++y)
    for (int x = 0; x < r.gbuffer.width_px(); ++x) {
      const float d = r.gbuffer.depth_view.at<float>(y, x);
      if (r.gbuffer.mask.at<uint8_t>(y, x)) {
        ASSERT_TRUE(std::isfinite(d));
      } else {
        ASSERT_TRUE(std::isinf(d));
      }
    }
}

TEST(ReadConversions, TiledMipmappedFileReadsItsFullResolutionLevel) {
  const fs::path path = conformance_dir() / "valid" / "MultiResolution" / "ColorCodedLevels.exr";
  SSDO_SKIP_WITHOUT(path);
  ReadOptions options;
  options.fov_x_deg = 40.0f;
  options.mapping.depth = "G";
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  int w = 0, h = 0;
  const auto g = read_channels_oiio(path, {"G"}, 0, &w, &h);
  ASSERT_EQ(r.gbuffer.width_px(), w);
  ASSERT_EQ(r.gbuffer.height_px(), h);
  for (int i = 0; i < w * h; i += 131) {
    if (!r.gbuffer.mask.at<uint8_t>(i / w, i % w)) continue;
    EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(i / w, i % w), g[i]);
  }
}

TEST(ReadConversions, NormalsFacingAwayAreFlippedAndWorldNormalsRotated) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.camera.json");
  // A 640x360 frame with the cornell sidecar: generic N in world space (sidecar camera).
  ScratchDir dir;
  const fs::path path = dir / "flip.exr";
  TestExr t = generic_frame(640, 360, 4.0f);
  // World +Y is (almost) the camera's viewing direction: the normal -Y faces the camera,
  // +Y faces away and must be flipped.
  const std::vector<float> ny(640 * 360, 1.0f);
  t.channels.push_back({"N.X", OIIO::TypeDesc::FLOAT, std::vector<float>(640 * 360, 0.0f)});
  t.channels.push_back({"N.Y", OIIO::TypeDesc::FLOAT, ny});
  t.channels.push_back({"N.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(640 * 360, 0.0f)});
  ASSERT_TRUE(t.write(path));
  fs::copy_file(gbuffer_dir() / "cornell.camera.json", dir / "flip.camera.json");
  const ReadResult r = read_gbuffer(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.uses[1].space, "world");
  const glm::mat4 w2c = json_matrix(read_json(gbuffer_dir() / "cornell.camera.json")["world_to_camera"]);
  const glm::vec3 expected = -glm::normalize(glm::vec3(w2c * glm::vec4(0, 1, 0, 0)));
  const cv::Vec3f n = r.gbuffer.normal_view.at<cv::Vec3f>(180, 320);
  EXPECT_NEAR(n[0], expected.x, 1e-5);
  EXPECT_NEAR(n[1], expected.y, 1e-5);
  EXPECT_NEAR(n[2], expected.z, 1e-5);
  EXPECT_GT(n[2], 0.9f);
}

// World-space normals under a camera without a pose (--fov, no sidecar or header matrices)
// cannot be rotated into view space: they are not read (rebuilt from depth later), with a
// note, instead of being taken as view-space normals.
TEST(ReadConversions, WorldNormalsUnderABareFovAreRebuiltNotMisread) {
  ScratchDir dir;
  const fs::path path = dir / "fov.exr";
  TestExr t = generic_frame(64, 36, 4.0f);
  add_constant_normals(t, {0.0f, 1.0f, 0.0f});
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  options.mapping.normal_space = Space::world;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.gbuffer.normal_view.empty());
  EXPECT_TRUE(r.info.normals_reconstructed);
  bool noted = false;
  for (const std::string& n : r.info.notes) noted |= n.find("world space and the camera (--fov) has no pose") != std::string::npos;
  EXPECT_TRUE(noted);
  // View-space normals under the same camera are read.
  options.mapping.normal_space = Space::view;
  const ReadResult view = read_gbuffer(path.string(), options);
  ASSERT_TRUE(view.ok()) << view.error;
  EXPECT_FALSE(view.gbuffer.normal_view.empty());
}

// Generic N of no stated space under a camera without a world transform (Arnold's N AOV is
// world space) is taken as view space only while its foreground normals face the eye: the
// world normal +Y read as view space faces away on every pixel above the centre row (its
// eye ray has y > 0), half the frame, so it is dropped and rebuilt from depth, with a note
// naming the channels and the fraction. Normals facing the eye are kept, and so are the
// same away-facing ones when the mapping says they are view space. The SIMD groups and
// the per-pixel path count alike (a width that leaves a tail, 1 and 2 threads).
TEST(ReadConversions, GenericNormalsFacingAwayUnderABareFovAreNotTakenAsView) {
  ScratchDir dir;
  const int w = 67, h = 36;
  TestExr away = generic_frame(w, h, 4.0f);
  add_constant_normals(away, {0.0f, 1.0f, 0.0f});
  ASSERT_TRUE(away.write(dir / "away.exr"));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    options.threads = threads;
    const ReadResult r = read_gbuffer((dir / "away.exr").string(), options);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.info.normals_facing_away_pixels, int64_t(w) * (h / 2));
    EXPECT_TRUE(r.gbuffer.normal_view.empty());
    EXPECT_TRUE(r.info.normals_reconstructed);
    for (const ChannelUse& u : r.info.uses) EXPECT_NE(u.input, "normal");
    ASSERT_FALSE(r.info.notes.empty());
    const std::string& note = r.info.notes.back();
    EXPECT_TRUE(contains(note, "normal channels N.{X,Y,Z} are not view space")) << note;
    EXPECT_TRUE(contains(note, "50% of the foreground normals face away")) << note;
    EXPECT_TRUE(contains(note, "--map normal-space=world")) << note;
  }
  // Stated view space is obeyed: the normals are read, turned to face the eye.
  options.mapping.normal_space = Space::view;
  const ReadResult stated = read_gbuffer((dir / "away.exr").string(), options);
  ASSERT_TRUE(stated.ok()) << stated.error;
  ASSERT_FALSE(stated.gbuffer.normal_view.empty());
  EXPECT_EQ(stated.gbuffer.normal_view.at<cv::Vec3f>(0, 0), cv::Vec3f(0, -1, 0));
  EXPECT_EQ(stated.gbuffer.normal_view.at<cv::Vec3f>(h - 1, 0), cv::Vec3f(0, 1, 0));
  // Normals facing the eye but on 2 of the 36 rows (5.6% > 5%) are refused; on one row
  // (2.8%) they are taken as view space.
  options.mapping.normal_space = Space::automatic;
  for (const int rows_away : {1, 2}) {
    SCOPED_TRACE(rows_away);
    TestExr facing = generic_frame(w, h, 4.0f);
    add_constant_normals(facing, {0.0f, 0.0f, 1.0f});
    for (int i = 0; i < rows_away * w; ++i) facing.channels[3].values[i] = -1.0f;  // top rows: N = -Z
    ASSERT_TRUE(facing.write(dir / "facing.exr"));
    const ReadResult r = read_gbuffer((dir / "facing.exr").string(), options);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.info.normals_facing_away_pixels, int64_t(rows_away) * w);
    EXPECT_EQ(r.gbuffer.normal_view.empty(), rows_away == 2);
    if (rows_away == 1) {
      EXPECT_EQ(r.info.uses[1].space, "view");
    }
  }
}

// Blender's normals mapped by their own name (--map normal=ViewLayer.Normal) are still the
// world-space normals the profile knows: under --fov they are rebuilt from depth, even
// where, as here, they happen to face the eye as view normals would.
TEST(ReadConversions, ProfileNormalsMappedByNameKeepTheirWorldSpace) {
  ScratchDir dir;
  TestExr t;
  t.width = t.height = 8;
  t.channels.push_back({"ViewLayer.Depth.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(64, 3.0f)});
  for (const char* c : {"ViewLayer.Normal.X", "ViewLayer.Normal.Y"})
    t.channels.push_back({c, OIIO::TypeDesc::FLOAT, std::vector<float>(64, 0.0f)});
  t.channels.push_back({"ViewLayer.Normal.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(64, 1.0f)});
  ASSERT_TRUE(t.write(dir / "blender.exr"));
  ReadOptions options;
  options.fov_x_deg = 50.0f;
  options.mapping.normal = "ViewLayer.Normal";
  const ReadResult r = read_gbuffer((dir / "blender.exr").string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.gbuffer.normal_view.empty());
  EXPECT_TRUE(r.info.normals_reconstructed);
  bool noted = false;
  for (const std::string& n : r.info.notes)
    noted |= contains(n, "ViewLayer.Normal.{X,Y,Z} are world space and the camera (--fov) has no pose");
  EXPECT_TRUE(noted);
  // A stated space still wins.
  options.mapping.normal_space = Space::view;
  const ReadResult stated = read_gbuffer((dir / "blender.exr").string(), options);
  ASSERT_TRUE(stated.ok()) << stated.error;
  ASSERT_FALSE(stated.gbuffer.normal_view.empty());
  EXPECT_EQ(stated.gbuffer.normal_view.at<cv::Vec3f>(4, 4), cv::Vec3f(0, 0, 1));
}

// Under --fov, pixels wider than tall (pixelAspectRatio, anamorphic plates) narrow the
// vertical field of view: the image is width x aspect / height as wide as tall.
TEST(ReadConversions, FovFollowsThePixelAspectRatio) {
  ScratchDir dir;
  const fs::path path = dir / "anamorphic.exr";
  TestExr t = generic_frame(320, 360, 4.0f);
  t.float_attributes.push_back({"PixelAspectRatio", 2.0f});
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 50.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  const double expected_y = 2.0 * std::atan(std::tan(glm::radians(25.0)) * 360.0 / (320.0 * 2.0));
  EXPECT_NEAR(r.info.fov_y_deg, glm::degrees(expected_y), 1e-3);
  EXPECT_NEAR(r.info.fov_x_deg, 50.0, 1e-3);
}

// An orthographic camera has no field of view: info gives the width and height its data
// window sees, in scene units.
TEST(ReadConversions, AnOrthographicCameraReportsItsViewSize) {
  ScratchDir dir;
  const fs::path path = dir / "ortho.exr";
  ASSERT_TRUE(generic_frame(32, 16, 3.0f).write(path));
  const nlohmann::json identity = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  const nlohmann::json projection = {{0.5, 0, 0, 0}, {0, 1.0, 0, 0}, {0, 0, -0.01, -1.001}, {0, 0, 0, 1}};
  std::ofstream(dir / "ortho.camera.json")
      << nlohmann::json{{"projection", projection}, {"world_to_camera", identity}, {"width", 32}, {"height", 16}}.dump();
  const ReadResult r = read_gbuffer(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_FALSE(r.gbuffer.camera.is_perspective());
  EXPECT_FLOAT_EQ(r.info.view_width, 4.0f);
  EXPECT_FLOAT_EQ(r.info.view_height, 2.0f);
  EXPECT_EQ(r.info.fov_x_deg, 0.0f);
}

// A space given alone (--map normal-space=view) applies to the detected channels: the
// profile stays the detected one, and the normals are taken as they are, not rotated.
TEST(ReadConversions, AnExplicitSpaceAloneAppliesToTheDetectedNormals) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "cornell.camera.json");
  ScratchDir dir;
  const fs::path path = dir / "space.exr";
  TestExr t = generic_frame(640, 360, 4.0f);
  add_constant_normals(t, {0.0f, 0.0f, 1.0f});
  ASSERT_TRUE(t.write(path));
  fs::copy_file(gbuffer_dir() / "cornell.camera.json", dir / "space.camera.json");
  ReadOptions options;
  options.mapping.normal_space = Space::view;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.profile, "generic");
  EXPECT_EQ(r.info.uses[1].space, "view");
  const cv::Vec3f n = r.gbuffer.normal_view.at<cv::Vec3f>(180, 320);  // +Z view: faces the camera
  EXPECT_FLOAT_EQ(n[0], 0.0f);
  EXPECT_FLOAT_EQ(n[1], 0.0f);
  EXPECT_FLOAT_EQ(n[2], 1.0f);
  // Without it the sidecar's camera makes them world normals, rotated into view space.
  const ReadResult world = read_gbuffer(path.string());
  ASSERT_TRUE(world.ok()) << world.error;
  EXPECT_EQ(world.info.uses[1].space, "world");
  EXPECT_LT(world.gbuffer.normal_view.at<cv::Vec3f>(180, 320)[2], 0.5f);
}

TEST(ReadConversions, RadialDepthBecomesPlanar) {
  ScratchDir dir;
  const int w = 64, h = 48;
  const float fov = 70.0f;
  const Camera cam = Camera::from_fov_x(w, h, fov);
  // A fronto-parallel plane at planar depth 5, stored as distance from the eye.
  TestExr t = generic_frame(w, h, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      t.channels[0].values[y * w + x] = glm::length(cam.view_from_pixel_depth({x + 0.5f, y + 0.5f}, 5.0f));
  const fs::path path = dir / "radial.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = fov;
  options.depth_kind = DepthKind::radial;
  options.read_positions = true;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.depth_kind, "radial");
  double max_err = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) max_err = std::max(max_err, std::abs(r.gbuffer.depth_view.at<float>(y, x) - 5.0));
  EXPECT_LT(max_err, 1e-5);
  // Neither normals nor positions in the file: reported missing, left empty (they are
  // rebuilt from depth by service/frame_inputs.h).
  EXPECT_TRUE(r.info.normals_reconstructed);
  EXPECT_TRUE(r.gbuffer.normal_view.empty());
  EXPECT_TRUE(r.info.positions_missing);
  EXPECT_TRUE(r.gbuffer.position_view.empty());
  for (const ChannelUse& u : r.info.uses) EXPECT_NE(u.input, "position");
}

TEST(ReadConversions, HalfDepthIsReadAsFloat) {
  ScratchDir dir;
  TestExr t = generic_frame(4, 4, 2.5f);
  t.channels[0].type = OIIO::TypeDesc::HALF;
  t.channels[0].values[5] = 1.0009765625f;  // 1 + 2^-10: exact in half
  const fs::path path = dir / "half.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 45.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.gbuffer.depth_view.type(), CV_32FC1);
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(1, 1), 1.0009765625f);
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(0, 0), 2.5f);
  EXPECT_TRUE(contains(r.info.channels[0], "Z (half)"));
}

TEST(ReadConversions, DataWindowOffsetIsThePixelGrid) {
  // Data window 32 x 16 at (10, 20) inside a 64 x 48 display window; depth encodes the
  // absolute pixel position, so row 0 / column 0 must be the data window's top-left.
  ScratchDir dir;
  TestExr t;
  t.width = 32;
  t.height = 16;
  t.data_x = 10;
  t.data_y = 20;
  t.display_width = 64;
  t.display_height = 48;
  std::vector<float> z;
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x) z.push_back(float(1000 * (y + t.data_y) + (x + t.data_x)));
  t.channels = {{"depth.Z", OIIO::TypeDesc::FLOAT, z}};
  const fs::path path = dir / "offset.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.data_x, 10);
  EXPECT_EQ(r.info.data_y, 20);
  EXPECT_EQ(r.info.display_width_px, 64);
  EXPECT_EQ(r.gbuffer.width_px(), 32);
  EXPECT_EQ(r.gbuffer.height_px(), 16);
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(0, 0), 20010.0f);
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(15, 31), 35041.0f);
  // The camera's field of view spans the display window: data pixel (0, 0) sees the ray of
  // display pixel (10, 20).
  const Camera display = Camera::from_fov_x(64, 48, 60.0f);
  const glm::vec3 a = r.gbuffer.camera.view_from_pixel_depth({0.5f, 0.5f}, 3.0f);
  const glm::vec3 b = display.view_from_pixel_depth({10.5f, 20.5f}, 3.0f);
  EXPECT_NEAR(glm::length(a - b), 0.0f, 1e-5f);
}

TEST(ReadConversions, ConformanceDisplayWindowFilesShareTheirPixels) {
  // t01: data window = display window; t08: the same 400 x 300 pixels with the data window
  // at (30, 40) inside a 501 x 401 display window.
  const fs::path t01 = conformance_dir() / "valid" / "DisplayWindow" / "t01.exr";
  const fs::path t08 = conformance_dir() / "valid" / "DisplayWindow" / "t08.exr";
  SSDO_SKIP_WITHOUT(t08);
  ReadOptions options;
  options.fov_x_deg = 60.0f;
  options.mapping.depth = "G";  // any channel serves as depth for the grid check
  const ReadResult a = read_gbuffer(t01.string(), options);
  const ReadResult b = read_gbuffer(t08.string(), options);
  ASSERT_TRUE(a.ok()) << a.error;
  ASSERT_TRUE(b.ok()) << b.error;
  EXPECT_EQ(a.info.profile, "mapping");
  EXPECT_EQ(b.info.data_x, 30);
  EXPECT_EQ(b.info.data_y, 40);
  ASSERT_EQ(a.gbuffer.depth_view.size(), b.gbuffer.depth_view.size());
  EXPECT_EQ(cv::countNonZero(a.gbuffer.mask != b.gbuffer.mask), 0);
  cv::Mat diff;
  cv::absdiff(a.gbuffer.depth_view, b.gbuffer.depth_view, diff);
  diff.setTo(0, a.gbuffer.mask == 0);
  double max_diff = 0;
  cv::minMaxLoc(diff, nullptr, &max_diff);
  EXPECT_EQ(max_diff, 0.0);
  EXPECT_GT(a.info.foreground_pixels, 1000);
}

TEST(ReadConversions, MultipartDepthOnlyPartWithFov) {
  const fs::path mp = conformance_dir() / "valid" / "Beachball" / "multipart.0001.exr";
  SSDO_SKIP_WITHOUT(mp);
  ReadOptions options;
  options.part = "depth_left";
  options.fov_x_deg = 40.0f;
  const ReadResult r = read_gbuffer(mp.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.parts.size(), 10u);
  EXPECT_EQ(r.info.part, "depth_left");
  EXPECT_EQ(r.info.profile, "generic");
  EXPECT_EQ(r.info.width_px, 877);
  EXPECT_EQ(r.info.height_px, 876);
  EXPECT_EQ(r.info.data_x, 688);
  EXPECT_EQ(r.info.data_y, 245);
  EXPECT_TRUE(r.info.normals_reconstructed);
  EXPECT_GT(r.info.foreground_pixels, 0);
  // Same samples as OpenImageIO reads from that part (subimage).
  int subimage = -1;
  {
    auto in = OIIO::ImageInput::open(mp.string());
    ASSERT_TRUE(in);
    for (int s = 0; in->seek_subimage(s, 0); ++s)
      if (in->spec().get_string_attribute("name") == "depth_left") subimage = s;
  }
  ASSERT_GE(subimage, 0);
  int w = 0, h = 0;
  const auto z = read_channels_oiio(mp, {"Z"}, subimage, &w, &h);
  ASSERT_EQ(w, 877);
  int64_t compared = 0;
  for (int i = 0; i < w * h; i += 97) {
    const int y = i / w, x = i % w;
    if (!r.gbuffer.mask.at<uint8_t>(y, x)) continue;
    EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(y, x), z[i]);
    ++compared;
  }
  EXPECT_GT(compared, 100);
  // Without --part the first part with depth is chosen: depth_left comes before depth_right.
  ReadOptions no_part;
  no_part.fov_x_deg = 40.0f;
  const ReadResult first = inspect_gbuffer(mp.string(), no_part);
  ASSERT_TRUE(first.ok()) << first.error;
  EXPECT_EQ(first.info.part, "depth_left");
}

TEST(ReadConversions, ExplicitMappingOverridesDetection) {
  ScratchDir dir;
  TestExr t = generic_frame(8, 8, 2.0f);
  t.channels.push_back({"dist", OIIO::TypeDesc::FLOAT, std::vector<float>(64, 7.0f)});
  for (const char* c : {"shade.R", "shade.G", "shade.B"})
    t.channels.push_back({c, OIIO::TypeDesc::HALF, std::vector<float>(64, 0.25f)});
  const fs::path path = dir / "mapped.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 50.0f;
  options.mapping.depth = "dist";
  options.mapping.lighting = "shade";
  options.mapping.references["occlusion"] = "shade.G";
  const ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.profile, "mapping");
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(3, 3), 7.0f);
  ASSERT_FALSE(r.gbuffer.lighting.empty());
  EXPECT_FLOAT_EQ(r.gbuffer.lighting.at<cv::Vec3f>(2, 2)[1], 0.25f);
  ASSERT_EQ(r.gbuffer.references.count("occlusion"), 1u);
  EXPECT_EQ(r.gbuffer.references.at("occlusion").type(), CV_32FC1);
}


// A Blender file with two view layers: the inputs come from one layer, never mixed: the
// first, with a warning naming the others, or the one whose depth the mapping names.
TEST(ReadConversions, TwoViewLayersAreNeverMixed) {
  ScratchDir dir;
  TestExr t;
  t.width = t.height = 8;
  auto layer = [&](const std::string& l, float depth, float normal_z, float albedo) {
    t.channels.push_back({l + ".Depth.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(64, depth)});
    for (const char* c : {".Normal.X", ".Normal.Y"}) t.channels.push_back({l + c, OIIO::TypeDesc::FLOAT, std::vector<float>(64, 0.0f)});
    t.channels.push_back({l + ".Normal.Z", OIIO::TypeDesc::FLOAT, std::vector<float>(64, normal_z)});
    for (const char* c : {".DiffCol.R", ".DiffCol.G", ".DiffCol.B"})
      t.channels.push_back({l + c, OIIO::TypeDesc::HALF, std::vector<float>(64, albedo)});
  };
  layer("A", 3.0f, 1.0f, 0.25f);
  layer("ViewLayer", 5.0f, 1.0f, 0.75f);
  const fs::path path = dir / "layers.exr";
  ASSERT_TRUE(t.write(path));
  ReadOptions options;
  options.fov_x_deg = 50.0f;
  ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.layer, "A");
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(3, 3), 3.0f);
  EXPECT_FLOAT_EQ(r.gbuffer.albedo.at<cv::Vec3f>(3, 3)[0], 0.25f);
  const std::string warning = "warning: view layers A, ViewLayer: the inputs are A's; --map depth=ViewLayer.Depth.Z reads another's";
  EXPECT_NE(std::find(r.info.notes.begin(), r.info.notes.end(), warning), r.info.notes.end());
  options.mapping.depth = "ViewLayer.Depth.Z";
  r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.info.layer, "ViewLayer");
  EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(3, 3), 5.0f);
  EXPECT_FLOAT_EQ(r.gbuffer.albedo.at<cv::Vec3f>(3, 3)[0], 0.75f);  // not A's
  for (const std::string& note : r.info.notes) EXPECT_NE(note.rfind("warning: ", 0), 0u) << note;
}

// ---------------------------------------------------------------------------------------
// The ZIP decoders: libdeflate (the default) against OpenEXR's own, bit for bit, and on
// damaged files.

// One channel written with OpenEXR itself as raw sample bits (half: the low 16 bits), so
// that NaN payloads and incompressible noise reach the file exactly as given.
struct RawChannel {
  std::string name;
  Imf::PixelType type;
  std::vector<uint32_t> bits;  // row-major, width x height
};

struct RawExr {
  int width = 0, height = 0;
  int data_x = 0, data_y = 0;  // data window origin; the display window is 0..63 x 0..63
  Imf::Compression compression = Imf::ZIP_COMPRESSION;
  Imf::LineOrder line_order = Imf::INCREASING_Y;
  std::vector<RawChannel> channels;

  void write(const fs::path& path) const {
    const Imath::Box2i window(Imath::V2i(data_x, data_y),
                              Imath::V2i(data_x + width - 1, data_y + height - 1));
    Imf::Header header(Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(63, 63)), window);
    header.compression() = compression;
    header.lineOrder() = line_order;
    std::vector<std::vector<uint16_t>> halves(channels.size());
    Imf::FrameBuffer fb;
    for (size_t c = 0; c < channels.size(); ++c) {
      const RawChannel& ch = channels[c];
      header.channels().insert(ch.name, Imf::Channel(ch.type));
      if (ch.type == Imf::HALF) {
        for (uint32_t b : ch.bits) halves[c].push_back(uint16_t(b));
        fb.insert(ch.name, Imf::Slice::Make(Imf::HALF, halves[c].data(), window, 2, 2 * size_t(width)));
      } else {
        fb.insert(ch.name, Imf::Slice::Make(ch.type, ch.bits.data(), window, 4, 4 * size_t(width)));
      }
    }
    Imf::OutputFile out(path.c_str(), header);
    out.setFrameBuffer(fb);
    out.writePixels(height);
  }
};

uint32_t float_bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

// A generic frame (Z float, N.{X,Y,Z} half, references A half and B float, and a uint
// channel nobody reads) of smooth values, except for the rows in [noise_from, noise_to),
// random bits in every channel (NaNs and infinities included).
RawExr zip_test_frame(int width, int height, int noise_from = 0, int noise_to = 0) {
  RawExr e;
  e.width = width;
  e.height = height;
  e.channels = {{"A", Imf::HALF, {}},     {"B", Imf::FLOAT, {}},   {"ID", Imf::UINT, {}},
                {"N.X", Imf::HALF, {}},   {"N.Y", Imf::HALF, {}},  {"N.Z", Imf::HALF, {}},
                {"Z", Imf::FLOAT, {}}};
  std::mt19937 rng(unsigned(width * 1000 + height));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const bool noise = y >= noise_from && y < noise_to;
      const float u = float(x) / float(width), v = float(y) / float(height);
      const uint32_t smooth[7] = {
          uint32_t(Imath::half(0.25f + 0.5f * u).bits()), float_bits(v * 3.0f - 1.0f),
          uint32_t(x * 7 + y), uint32_t(Imath::half(0.3f * u).bits()),
          uint32_t(Imath::half(-0.2f * v).bits()), uint32_t(Imath::half(0.9f).bits()),
          float_bits(2.0f + 0.05f * float(x) + 0.01f * float(y))};
      for (size_t c = 0; c < e.channels.size(); ++c)
        e.channels[c].bits.push_back(noise ? uint32_t(rng()) : smooth[c]);
    }
  // Half samples: 16 random bits, not 32.
  for (auto& c : e.channels)
    if (c.type == Imf::HALF)
      for (auto& b : c.bits) b &= 0xffff;
  // One half NaN with a payload, one float signalling NaN: both must arrive unchanged.
  e.channels[0].bits[1] = 0x7d01;
  e.channels[1].bits[2] = 0x7f800001;
  return e;
}

ReadOptions zip_test_options() {
  ReadOptions o;
  o.fov_x_deg = 50.0f;
  o.mapping.references = {{"a", "A"}, {"b", "B"}};
  return o;
}

void expect_bit_identical(const cv::Mat& a, const cv::Mat& b, const std::string& what) {
  ASSERT_EQ(a.empty(), b.empty()) << what;
  ASSERT_EQ(a.size(), b.size()) << what;
  ASSERT_EQ(a.type(), b.type()) << what;
  for (int y = 0; y < a.rows; ++y)
    ASSERT_EQ(std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()), 0) << what << " row " << y;
}

// Reads `path` with OpenEXR's decoder and with libdeflate (serially and on 2 threads) and
// expects every image bit for bit and every count equal. Returns the OpenEXR read.
ReadResult expect_same_reads(const fs::path& path, ReadOptions options) {
  options.zip_decoder = ZipDecoder::openexr;
  const ReadResult reference = read_gbuffer(path.string(), options);
  EXPECT_TRUE(reference.ok()) << reference.error;
  for (int threads : {1, 2}) {
    SCOPED_TRACE(path.filename().string() + ", threads " + std::to_string(threads));
    options.zip_decoder = ZipDecoder::libdeflate;
    options.threads = threads;
    const ReadResult r = read_gbuffer(path.string(), options);
    EXPECT_TRUE(r.ok()) << r.error;
    if (!r.ok() || !reference.ok()) continue;
    const GBuffer &a = r.gbuffer, &b = reference.gbuffer;
    expect_bit_identical(a.depth_view, b.depth_view, "depth");
    expect_bit_identical(a.mask, b.mask, "mask");
    expect_bit_identical(a.normal_view, b.normal_view, "normal");
    expect_bit_identical(a.normal_missing, b.normal_missing, "normal_missing");
    expect_bit_identical(a.position_view, b.position_view, "position");
    expect_bit_identical(a.albedo, b.albedo, "albedo");
    expect_bit_identical(a.lighting, b.lighting, "lighting");
    EXPECT_EQ(a.references.size(), b.references.size());
    for (const auto& [name, m] : b.references) {
      EXPECT_EQ(a.references.count(name), 1u) << name;
      if (a.references.count(name)) expect_bit_identical(a.references.at(name), m, "reference " + name);
    }
    EXPECT_EQ(r.info.foreground_pixels, reference.info.foreground_pixels);
    EXPECT_EQ(r.info.nonfinite_pixels, reference.info.nonfinite_pixels);
    EXPECT_EQ(r.info.repaired_normal_pixels, reference.info.repaired_normal_pixels);
  }
  return reference;
}

// Packed and unpacked sizes of every chunk of part 0, read with OpenEXRCore.
std::vector<std::pair<uint64_t, uint64_t>> chunk_sizes(const fs::path& path) {
  std::vector<std::pair<uint64_t, uint64_t>> sizes;
  exr_context_t ctx = nullptr;
  if (exr_start_read(&ctx, path.c_str(), nullptr) != EXR_ERR_SUCCESS) return sizes;
  exr_attr_box2i_t dw;
  int32_t lines = 0;
  exr_get_data_window(ctx, 0, &dw);
  exr_get_scanlines_per_chunk(ctx, 0, &lines);
  for (int y = dw.min.y; y <= dw.max.y; y += lines) {
    exr_chunk_info_t c{};
    if (exr_read_scanline_chunk_info(ctx, 0, y, &c) != EXR_ERR_SUCCESS) break;
    sizes.emplace_back(c.packed_size, c.unpacked_size);
  }
  exr_finish(&ctx);
  return sizes;
}

TEST(ZipDecoders, HalfAndFloatChannelsAreBitIdenticalForEveryLayout) {
  ScratchDir dir;
  // 45 lines: the last ZIP chunk holds 13; the data window starts off the origin.
  RawExr e = zip_test_frame(37, 45);
  e.data_x = -5;
  e.data_y = 7;
  for (auto compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION, Imf::NO_COMPRESSION})
    for (auto order : {Imf::INCREASING_Y, Imf::DECREASING_Y}) {
      e.compression = compression;
      e.line_order = order;
      const fs::path path =
          dir / ("frame_" + std::to_string(int(compression)) + "_" + std::to_string(int(order)) + ".exr");
      e.write(path);
      const ReadResult r = expect_same_reads(path, zip_test_options());
      ASSERT_TRUE(r.ok()) << r.error;
      // And the values are the file's (not merely the same wrong ones twice).
      const cv::Mat& a = r.gbuffer.references.at("a");
      const cv::Mat& b = r.gbuffer.references.at("b");
      EXPECT_FLOAT_EQ(a.at<float>(44, 36), float(Imath::half(0.25f + 0.5f * 36.0f / 37.0f)));
      EXPECT_FLOAT_EQ(b.at<float>(44, 0), 44.0f / 45.0f * 3.0f - 1.0f);
      EXPECT_EQ(float_bits(b.at<float>(0, 2)), 0x7f800001u);
      EXPECT_FLOAT_EQ(r.gbuffer.depth_view.at<float>(0, 0), 2.0f);
    }
}

TEST(ZipDecoders, EveryHalfValueConvertsAsImathDoes) {
  ScratchDir dir;
  // Reference A holds each of the 65536 half values once (NaNs with every payload among
  // them): vector groups with and without a NaN, at every alignment the rows give.
  RawExr e = zip_test_frame(256, 256);
  for (uint32_t i = 0; i < 65536; ++i) e.channels[0].bits[i] = i;
  const fs::path path = dir / "every_half.exr";
  e.write(path);
  ReadOptions options;
  options.fov_x_deg = 50.0f;
  options.mapping.references.emplace("a", "A");
  const ReadResult r = expect_same_reads(path, options);
  ASSERT_TRUE(r.ok()) << r.error;
  const cv::Mat& a = r.gbuffer.references.at("a");
  for (uint32_t i = 0; i < 65536; ++i)
    ASSERT_EQ(float_bits(a.at<float>(int(i / 256), int(i % 256))),
              float_bits(imath_half_to_float_table[i].f))
        << "half bits " << i;
}

TEST(ZipDecoders, IncompressibleChunkStoredAsIsIsBitIdentical) {
  ScratchDir dir;
  for (auto compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION}) {
    // Rows 16..31: the second ZIP chunk (16 ZIPS chunks) is noise in every channel.
    RawExr e = zip_test_frame(40, 50, 16, 32);
    e.compression = compression;
    const fs::path path = dir / ("noise_" + std::to_string(int(compression)) + ".exr");
    e.write(path);
    const auto sizes = chunk_sizes(path);
    ASSERT_FALSE(sizes.empty());
    int stored = 0, deflated = 0;
    for (const auto& [packed, unpacked] : sizes) {
      stored += packed == unpacked ? 1 : 0;
      deflated += packed < unpacked ? 1 : 0;
    }
    EXPECT_GT(stored, 0) << "the noise chunk must be stored as is";
    EXPECT_GT(deflated, 0);
    expect_same_reads(path, zip_test_options());
  }
}

TEST(ZipDecoders, SharedFramesAreBitIdentical) {
  SSDO_SKIP_WITHOUT(gbuffer_dir() / "perf1080.exr");
  ReadOptions all;
  all.read_positions = true;
  expect_same_reads(gbuffer_dir() / "perf1080.exr", all);
  expect_same_reads(gbuffer_dir() / "cornell.exr", all);
  // OpenEXR's own ZIP (half RGB with NaN and Inf) and ZIPS (20 channels) images.
  ReadOptions rgb;
  rgb.fov_x_deg = 60.0f;
  rgb.mapping.depth = "R";
  rgb.mapping.references["g"] = "G";
  rgb.mapping.references["b"] = "B";
  for (const char* name : {"TestImages/BrightRingsNanInf.exr", "TestImages/WideColorGamut.exr",
                           "Beachball/singlepart.0001.exr"}) {
    const fs::path path = conformance_dir() / "valid" / name;
    if (fs::exists(path)) expect_same_reads(path, rgb);
  }
  // A part of a multi-part ZIPS file (chunk leaders carry the part number).
  const fs::path mp = conformance_dir() / "valid" / "Beachball" / "multipart.0001.exr";
  if (fs::exists(mp)) {
    ReadOptions part;
    part.part = "depth_left";
    part.fov_x_deg = 40.0f;
    expect_same_reads(mp, part);
  }
}

// Both decoders refuse the file with the reader's message for damaged files.
void expect_both_refuse(const fs::path& path, const std::string& libdeflate_says = "") {
  for (ZipDecoder decoder : {ZipDecoder::openexr, ZipDecoder::libdeflate}) {
    SCOPED_TRACE(decoder == ZipDecoder::openexr ? "openexr" : "libdeflate");
    ReadOptions options = zip_test_options();
    options.zip_decoder = decoder;
    options.threads = 2;
    const ReadResult r = read_gbuffer(path.string(), options);
    ASSERT_FALSE(r.ok());
    EXPECT_TRUE(contains(r.error, path.string())) << r.error;
    EXPECT_TRUE(contains(r.error, "truncated")) << r.error;
    EXPECT_TRUE(r.gbuffer.depth_view.empty());
    if (decoder == ZipDecoder::libdeflate && !libdeflate_says.empty()) {
      EXPECT_TRUE(contains(r.error, libdeflate_says)) << r.error;
    }
  }
}

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(ZipDecoders, TruncatedZipFilesFailCleanly) {
  ScratchDir dir;
  RawExr e = zip_test_frame(64, 80);
  const fs::path whole = dir / "whole.exr";
  e.write(whole);
  const std::string bytes = file_bytes(whole);
  const auto sizes = chunk_sizes(whole);
  ASSERT_EQ(sizes.size(), 5u);
  // Inside the fourth chunk, halfway through the file, halfway through the last chunk, one
  // byte short.
  for (size_t n : {bytes.size() - sizes.back().first - 100, bytes.size() / 2,
                   bytes.size() - sizes.back().first / 2, bytes.size() - 1}) {
    SCOPED_TRACE(n);
    const fs::path path = dir / ("cut_" + std::to_string(n) + ".exr");
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(n));
    expect_both_refuse(path);
  }
}

TEST(ZipDecoders, CorruptedChunkFailsCleanlyNamingItsScanline) {
  ScratchDir dir;
  RawExr e = zip_test_frame(64, 80);
  e.data_y = 100;
  const fs::path whole = dir / "whole.exr";
  e.write(whole);
  const std::string bytes = file_bytes(whole);
  // The third chunk (scanlines 132..147): where its leader and data are.
  exr_context_t ctx = nullptr;
  ASSERT_EQ(exr_start_read(&ctx, whole.c_str(), nullptr), EXR_ERR_SUCCESS);
  exr_chunk_info_t chunk{};
  ASSERT_EQ(exr_read_scanline_chunk_info(ctx, 0, 132, &chunk), EXR_ERR_SUCCESS);
  exr_finish(&ctx);
  ASSERT_LT(chunk.packed_size, chunk.unpacked_size);
  const size_t data = size_t(chunk.data_offset), leader = data - 8;  // y, packed size
  auto damaged = [&](const std::string& name, auto&& edit) {
    std::string b = bytes;
    edit(b);
    const fs::path path = dir / (name + ".exr");
    std::ofstream(path, std::ios::binary).write(b.data(), std::streamsize(b.size()));
    return path;
  };
  // Garbage in the middle of the deflate stream.
  expect_both_refuse(damaged("garbage", [&](std::string& b) {
                       for (size_t i = 0; i < 24; ++i) b[data + chunk.packed_size / 2 + i] = char(0xA5);
                     }),
                     "scanline 132");
  // A leader naming another scanline.
  expect_both_refuse(damaged("wrong_y", [&](std::string& b) {
                       const int32_t y = 148;
                       std::memcpy(&b[leader], &y, 4);
                     }),
                     "scanline 132");
  // A leader claiming more bytes than the chunk's pixels.
  expect_both_refuse(damaged("too_large", [&](std::string& b) {
                       const int32_t n = int32_t(chunk.unpacked_size) + 64;
                       std::memcpy(&b[leader + 4], &n, 4);
                     }),
                     "scanline 132");
  // A leader claiming fewer bytes than the stream holds (the stream ends early).
  expect_both_refuse(damaged("too_small", [&](std::string& b) {
                       const int32_t n = int32_t(chunk.packed_size / 2);
                       std::memcpy(&b[leader + 4], &n, 4);
                     }),
                     "scanline 132");
}

// Random bytes anywhere in the chunks (leaders, deflate streams, the chunk stored as is):
// the decoders read the same files, to the same bits, and refuse the same files.
TEST(ZipDecoders, RandomlyDamagedChunksAreReadOrRefusedAlike) {
  ScratchDir dir;
  RawExr e = zip_test_frame(48, 70, 16, 32);  // the second chunk is stored as is
  const fs::path whole = dir / "whole.exr";
  e.write(whole);
  const std::string bytes = file_bytes(whole);
  size_t chunks_at = bytes.size();
  for (const auto& [packed, unpacked] : chunk_sizes(whole)) chunks_at -= size_t(packed) + 8;
  std::mt19937 rng(11);
  int both_read = 0, both_refused = 0;
  for (int k = 0; k < 300; ++k) {
    std::string b = bytes;
    const int changes = 1 + int(rng() % 4);
    for (int i = 0; i < changes; ++i) b[chunks_at + rng() % (b.size() - chunks_at)] = char(rng());
    const fs::path path = dir / "damaged.exr";
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(b.data(), std::streamsize(b.size()));
    ReadOptions options = zip_test_options();
    options.zip_decoder = ZipDecoder::openexr;
    const ReadResult theirs = read_gbuffer(path.string(), options);
    options.zip_decoder = ZipDecoder::libdeflate;
    const ReadResult ours = read_gbuffer(path.string(), options);
    ASSERT_EQ(ours.ok(), theirs.ok()) << "case " << k << ": " << ours.error << " | " << theirs.error;
    if (ours.ok()) {
      ++both_read;
      expect_bit_identical(ours.gbuffer.references.at("a"), theirs.gbuffer.references.at("a"), "a");
      expect_bit_identical(ours.gbuffer.references.at("b"), theirs.gbuffer.references.at("b"), "b");
      expect_bit_identical(ours.gbuffer.depth_view, theirs.gbuffer.depth_view, "depth");
    } else {
      ++both_refused;
      EXPECT_TRUE(contains(ours.error, "damaged or truncated")) << ours.error;
    }
  }
  // Both outcomes occur (damage inside the stored chunk is not detectable).
  EXPECT_GT(both_read, 0);
  EXPECT_GT(both_refused, 0);
}

}  // namespace
}  // namespace ssdo::test
