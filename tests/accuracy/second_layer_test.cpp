// Second depth layers from files: the thin-occluder case of the failure suite written by the
// reference ray caster as (a) a deep EXR (every surface crossing of each pixel's ray a
// sample, through OpenEXR's deep API) and (b) a flat EXR with a back-face depth channel,
// read back with read_frame: depth and back depth per pixel against the ray caster's, and
// the AO error against its exact AO with the back layer and without it.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDeepFrameBuffer.h>
#include <OpenEXR/ImfDeepScanLineOutputFile.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfPartType.h>

#include "failure_cases.h"
#include "service/frame_inputs.h"
#include "service/pipeline.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

struct Scratch {
  fs::path path;
  Scratch() {
    std::random_device rd;
    path = fs::temp_directory_path() / ("ssdo_second_layer_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

// The thin case (poles and a plate in front of a wall) as the ray caster sees it.
struct ThinCase {
  raycast::Scene scene = failure::thin_scene();
  failure::Frame frame = failure::clean_frame(scene, raycast::poles_camera(failure::kWidth, failure::kHeight));
  std::vector<std::vector<float>> samples = raycast::render_depth_samples(scene, frame.input.camera, 0);
};

const ThinCase& thin_case() {
  static const ThinCase c;
  return c;
}

// Radial distance of planar depth d on pixel (x, y): d |ray| for the ray with z = -1.
float radial_of(const Camera& camera, int x, int y, float planar) {
  if (!std::isfinite(planar)) return planar;
  return planar * glm::length(camera.view_from_pixel_depth({float(x) + 0.5f, float(y) + 0.5f}, 1.0f));
}

// A flat float EXR of the named images (one channel each).
void write_flat(const fs::path& path, const std::vector<std::pair<std::string, cv::Mat>>& channels) {
  const cv::Mat& first = channels.front().second;
  Imf::Header header(first.cols, first.rows);
  header.compression() = Imf::ZIP_COMPRESSION;
  Imf::FrameBuffer fb;
  for (const auto& [name, m] : channels) {
    header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    fb.insert(name, Imf::Slice(Imf::FLOAT, const_cast<char*>(m.ptr<char>()), 4, m.step[0]));
  }
  Imf::OutputFile out(path.c_str(), header);
  out.setFrameBuffer(fb);
  out.writePixels(first.rows);
}

// Depth Z and view-space normal N of the G-buffer, radial depth if asked, and the back-face
// pass as `back_name` ("" = none).
void write_flat_frame(const fs::path& path, const ThinCase& c, bool radial, const std::string& back_name) {
  const GBuffer& g = c.frame.input;
  cv::Mat z = g.depth_view.clone(), back = g.depth_back_view.clone();
  if (radial)
    for (int y = 0; y < z.rows; ++y)
      for (int x = 0; x < z.cols; ++x) {
        z.at<float>(y, x) = radial_of(g.camera, x, y, z.at<float>(y, x));
        back.at<float>(y, x) = radial_of(g.camera, x, y, back.at<float>(y, x));
      }
  std::vector<cv::Mat> n(3);
  cv::split(g.normal_view, n);
  std::vector<std::pair<std::string, cv::Mat>> channels{{"Z", z}, {"N.X", n[0]}, {"N.Y", n[1]}, {"N.Z", n[2]}};
  if (!back_name.empty()) channels.push_back({back_name, back});
  write_flat(path, channels);
}

// Every crossing a sample (Z, ZBack = Z, N), farthest first (deep samples need not be
// sorted); N is the G-buffer's normal on the nearest sample, its opposite on the others.
void write_deep_frame(const fs::path& path, const ThinCase& c) {
  const GBuffer& g = c.frame.input;
  const int w = g.depth_view.cols, h = g.depth_view.rows;
  Imf::Header header(w, h);
  header.setType(Imf::DEEPSCANLINE);
  header.compression() = Imf::ZIPS_COMPRESSION;
  const char* names[5] = {"Z", "ZBack", "N.X", "N.Y", "N.Z"};
  for (const char* name : names) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
  std::vector<uint32_t> counts(size_t(w) * h);
  std::vector<std::vector<float>> values(5);
  std::vector<size_t> first(counts.size());
  for (size_t i = 0; i < counts.size(); ++i) {
    const std::vector<float>& s = c.samples[i];
    counts[i] = uint32_t(s.size());
    first[i] = values[0].size();
    const cv::Vec3f n = g.normal_view.at<cv::Vec3f>(int(i) / w, int(i) % w);
    for (size_t k = s.size(); k-- > 0;) {
      const float sign = k == 0 ? 1.0f : -1.0f;
      const float v[5] = {s[k], s[k], sign * n[0], sign * n[1], sign * n[2]};
      for (int ch = 0; ch < 5; ++ch) values[ch].push_back(v[ch]);
    }
  }
  std::vector<std::vector<float*>> pointers(5, std::vector<float*>(counts.size()));
  Imf::DeepFrameBuffer fb;
  fb.insertSampleCountSlice(Imf::Slice(Imf::UINT, reinterpret_cast<char*>(counts.data()), 4, 4 * size_t(w)));
  for (int ch = 0; ch < 5; ++ch) {
    for (size_t i = 0; i < counts.size(); ++i) pointers[ch][i] = values[ch].data() + first[i];
    fb.insert(names[ch], Imf::DeepSlice(Imf::FLOAT, reinterpret_cast<char*>(pointers[ch].data()), sizeof(float*),
                                        sizeof(float*) * w, sizeof(float)));
  }
  Imf::DeepScanLineOutputFile out(path.c_str(), header);
  out.setFrameBuffer(fb);
  out.writePixels(h);
}

// The next distinct surface behind the nearest sample, as the reader defines it.
float next_surface(const std::vector<float>& s) {
  for (size_t k = 1; k < s.size(); ++k)
    if (s[k] > s[0] * (1.0f + kDeepSurfaceGapRelative)) return s[k];
  return failure::kInf;
}

ReadResult read_thin(const fs::path& path, const ReadOptions& base = {}) {
  ReadOptions options = base;
  options.fov_x_deg = thin_case().frame.input.camera.fov_x_deg();
  ReadResult r = read_frame(path.string(), options);
  EXPECT_TRUE(r.ok()) << r.error;
  return r;
}

TEST(SecondLayer, DeepFileGivesNearestSampleAndNextSurfacePerPixel) {
  const ThinCase& c = thin_case();
  Scratch dir;
  const fs::path path = dir.path / "thin_deep.exr";
  write_deep_frame(path, c);
  const ReadResult r = read_thin(path);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.info.back_layer, "deep samples of Z");
  const GBuffer& g = r.gbuffer, &truth = c.frame.input;
  ASSERT_EQ(g.depth_back_view.size(), truth.depth_view.size());
  int64_t with_back = 0;
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      const size_t i = size_t(y) * g.depth_view.cols + x;
      ASSERT_EQ(g.mask.at<uint8_t>(y, x), truth.mask.at<uint8_t>(y, x)) << x << "," << y;
      if (!truth.mask.at<uint8_t>(y, x)) {
        EXPECT_EQ(g.depth_back_view.at<float>(y, x), failure::kInf);
        continue;
      }
      EXPECT_FLOAT_EQ(g.depth_view.at<float>(y, x), c.samples[i][0]) << x << "," << y;
      EXPECT_FLOAT_EQ(g.depth_view.at<float>(y, x), truth.depth_view.at<float>(y, x)) << x << "," << y;
      EXPECT_EQ(g.depth_back_view.at<float>(y, x), next_surface(c.samples[i])) << x << "," << y;
      // The normal is the nearest sample's (the others carry its opposite).
      EXPECT_GT(g.normal_view.at<cv::Vec3f>(y, x).dot(truth.normal_view.at<cv::Vec3f>(y, x)), 0.999f);
      // Each pole and the plate: the next surface is the back face of the ray caster's pass,
      // except where a ray grazes an edge (entry and exit closer than the reader's gap).
      const float front = truth.depth_view.at<float>(y, x), back = truth.depth_back_view.at<float>(y, x);
      if (std::isfinite(back) && back > front * (1.0f + kDeepSurfaceGapRelative)) {
        ++with_back;
        EXPECT_NEAR(g.depth_back_view.at<float>(y, x), truth.depth_back_view.at<float>(y, x),
                    1e-5f * truth.depth_back_view.at<float>(y, x));
      }
    }
  EXPECT_GT(with_back, 200);  // the poles and the plate cover a few hundred pixels
}

TEST(SecondLayer, BackFaceChannelGetsTheDepthsConversion) {
  const ThinCase& c = thin_case();
  Scratch dir;
  const fs::path path = dir.path / "thin_back.exr";
  write_flat_frame(path, c, true, "Z.back");
  ReadOptions radial;
  radial.depth_kind = DepthKind::radial;
  const ReadResult r = read_thin(path, radial);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.info.back_layer, "channel Z.back");
  const GBuffer& g = r.gbuffer, &truth = c.frame.input;
  for (int y = 0; y < g.depth_view.rows; ++y)
    for (int x = 0; x < g.depth_view.cols; ++x) {
      const float want = truth.mask.at<uint8_t>(y, x) ? truth.depth_back_view.at<float>(y, x) : failure::kInf;
      const float got = g.depth_back_view.at<float>(y, x);
      if (!std::isfinite(want)) {
        EXPECT_EQ(got, failure::kInf) << x << "," << y;
      } else {
        EXPECT_NEAR(got, want, 1e-5f * want) << x << "," << y;
        EXPECT_GE(got, g.depth_view.at<float>(y, x));
      }
    }
  // Another name, mapped.
  write_flat_frame(path, c, false, "backface");
  ReadOptions mapped;
  mapped.mapping.depth_back = "backface";
  const ReadResult m = read_thin(path, mapped);
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m.info.back_layer, "channel backface");
  EXPECT_EQ(cv::norm(m.gbuffer.depth_back_view, r.gbuffer.depth_back_view, cv::NORM_INF) < 1e-4, true);
  // Not read when not asked for.
  ReadOptions without = mapped;
  without.read_depth_back = false;
  const ReadResult n = read_thin(path, without);
  EXPECT_TRUE(n.gbuffer.depth_back_view.empty());
  EXPECT_EQ(n.info.back_layer, "");
}

// MAE of the pipeline's raw AO of a file against the ray caster's exact AO (the clean
// frame's foreground), with the preset's thickness model where the file has no back layer
// or the one given.
double ao_error(const fs::path& path, AoMethod method, Preset preset,
                std::optional<ThicknessModel> model = std::nullopt) {
  FrameRequest request;
  request.terms.ao = true;
  request.terms.composite = false;
  request.ao = ao_preset(method, preset);
  request.ao.radius_world = failure::kRadius;
  if (model) request.ao.thickness_model = *model;
  request.read = reads_for(request);
  const ReadResult r = read_thin(path, request.read);
  const ComputedFrame out = compute_frame(r.gbuffer, request);
  const cv::Mat* ao = out.find("ao");
  if (!ao) return 1.0;
  return failure::errors(*ao, thin_case().frame.reference, thin_case().frame.eval_mask).mae;
}

// The back layer replaces the 0.5 x radius thickness guess by each tap's own thickness:
// the halo of the poles and the plate on the wall behind them goes. Measured (160 x 90,
// radius 1, MAE without -> back channel / deep): raymarch low 0.100 -> 0.018 / 0.021, gtao
// high 0.083 -> 0.027 / 0.029 (deep a little above the channel: rays grazing an edge,
// whose entry and exit lie within the reader's surface gap, keep the guess). Asserted: at
// most half the error without. GTAO's presets estimate the layer from the silhouettes
// where the file has none (0.031 here): the file's own layer still errs less.
TEST(SecondLayer, DeepFileAndBackChannelLowerTheThinOccluderError) {
  const ThinCase& c = thin_case();
  Scratch dir;
  const fs::path flat = dir.path / "thin.exr", back = dir.path / "thin_back.exr", deep = dir.path / "thin_deep.exr";
  write_flat_frame(flat, c, false, "");
  write_flat_frame(back, c, false, "depth_back");
  write_deep_frame(deep, c);
  struct Estimator {
    AoMethod method;
    Preset preset;
  };
  for (const Estimator& e : {Estimator{AoMethod::raymarch, Preset::low}, Estimator{AoMethod::gtao, Preset::high}}) {
    const double without = ao_error(flat, e.method, e.preset, ThicknessModel::constant),
                 with_channel = ao_error(back, e.method, e.preset), with_deep = ao_error(deep, e.method, e.preset);
    std::printf("thin occluders, %s %s: MAE without %.4f, back channel %.4f, deep %.4f\n",
                std::string(to_string(e.method)).c_str(), std::string(to_string(e.preset)).c_str(), without,
                with_channel, with_deep);
    EXPECT_LT(with_channel, 0.5 * without) << to_string(e.method);
    EXPECT_LT(with_deep, 0.5 * without) << to_string(e.method);
    if (e.method == AoMethod::gtao) {
      const double estimated = ao_error(flat, e.method, e.preset);
      std::printf("  the layer estimated from the silhouettes: %.4f\n", estimated);
      EXPECT_LT(with_channel, estimated);
      EXPECT_LT(estimated, 0.5 * without);
    }
  }
}

}  // namespace
}  // namespace ssdo
