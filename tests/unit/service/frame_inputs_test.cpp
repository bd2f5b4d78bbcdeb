// complete_gbuffer: what the reader reports missing (no normals, zero normals, no
// positions) is rebuilt from depth with the kernels, bit for bit as they compute it.
#include "service/frame_inputs.h"

#include <cstring>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>

#include "formats/output_writer.h"
#include "kernels/normals.h"
#include "kernels/positions.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

struct ScratchDir {
  fs::path path;
  ScratchDir() {
    std::random_device rd;
    path = fs::temp_directory_path() / ("ssdo_frame_inputs_test_" + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

constexpr int kWidth = 24, kHeight = 16;

// A slanted plane (planar depth 3 + 0.05 x + 0.02 y) with a background corner, written as
// a generic frame (Z, and N = (0, 0, 1) except at `zero_normals` when `normals`), its camera
// in the header.
fs::path write_frame(const ScratchDir& dir, bool normals, const std::vector<int>& zero_normals = {}) {
  cv::Mat z(kHeight, kWidth, CV_32FC1);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) z.at<float>(y, x) = x + y < 4 ? 1e10f : 3.0f + 0.05f * x + 0.02f * y;
  std::vector<OutputTerm> terms{{"Z", z, SampleType::float32, false}};
  if (normals) {
    cv::Mat n(kHeight, kWidth, CV_32FC3, cv::Scalar(0, 0, 1));
    for (int i : zero_normals) n.at<cv::Vec3f>(i / kWidth, i % kWidth) = cv::Vec3f(0, 0, 0);
    terms.push_back({"N", n, SampleType::float32, true});
  }
  const fs::path path = dir.path / (normals ? "with_normals.exr" : "depth_only.exr");
  const std::string error = write_outputs(path.string(), terms, Camera::from_fov_x(kWidth, kHeight, 50.0f));
  EXPECT_TRUE(error.empty()) << error;
  return path;
}

bool same_bits(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

TEST(CompleteGBuffer, FrameWithoutNormalsGetsTheNormalsReconstructedFromDepth) {
  ScratchDir dir;
  const fs::path path = write_frame(dir, false);
  for (int threads : {1, 2}) {
    ReadResult r = read_gbuffer(path.string());
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_TRUE(r.gbuffer.normal_view.empty());
    EXPECT_TRUE(r.info.normals_reconstructed);
    complete_gbuffer(r, threads);
    ASSERT_TRUE(r.ok()) << r.error;
    cv::Mat expected;
    reconstruct_normals_from_depth(r.gbuffer.depth_view, r.gbuffer.mask, r.gbuffer.camera, expected, {}, 1);
    EXPECT_TRUE(same_bits(r.gbuffer.normal_view, expected)) << threads << " threads";
    // The plane's normals face the camera.
    EXPECT_GT(r.gbuffer.normal_view.at<cv::Vec3f>(8, 12)[2], 0.9f);
    EXPECT_TRUE(r.gbuffer.position_view.empty());  // not asked for
  }
}

TEST(CompleteGBuffer, ZeroNormalsAreReplacedByReconstructedOnesAndTheOthersKept) {
  ScratchDir dir;
  const std::vector<int> zero = {5 * kWidth + 7, 9 * kWidth + 20};
  const fs::path path = write_frame(dir, true, zero);
  ReadResult r = read_gbuffer(path.string());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_FALSE(r.info.normals_reconstructed);
  EXPECT_EQ(r.info.repaired_normal_pixels, 2);
  EXPECT_EQ(cv::countNonZero(r.gbuffer.normal_missing), 2);
  complete_gbuffer(r, 2);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.gbuffer.normal_missing.empty());
  ASSERT_FALSE(r.info.notes.empty());
  EXPECT_EQ(r.info.notes.back(), "2 foreground pixels had a zero normal: reconstructed from depth");
  cv::Mat rebuilt;
  reconstruct_normals_from_depth(r.gbuffer.depth_view, r.gbuffer.mask, r.gbuffer.camera, rebuilt, {}, 1);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const cv::Vec3f n = r.gbuffer.normal_view.at<cv::Vec3f>(y, x);
      const bool repaired = std::find(zero.begin(), zero.end(), y * kWidth + x) != zero.end();
      if (!r.gbuffer.mask.at<uint8_t>(y, x))
        EXPECT_EQ(n, cv::Vec3f(0, 0, 0));
      else if (repaired)
        EXPECT_EQ(std::memcmp(&n, &rebuilt.at<cv::Vec3f>(y, x), sizeof n), 0) << x << "," << y;
      else
        EXPECT_EQ(n, cv::Vec3f(0, 0, 1)) << x << "," << y;
    }
  // A second completion has nothing left to do.
  const cv::Mat before = r.gbuffer.normal_view.clone();
  const size_t notes = r.info.notes.size();
  complete_gbuffer(r, 1);
  EXPECT_TRUE(same_bits(r.gbuffer.normal_view, before));
  EXPECT_EQ(r.info.notes.size(), notes);
}

TEST(CompleteGBuffer, MissingPositionsAreComputedFromDepth) {
  ScratchDir dir;
  const fs::path path = write_frame(dir, true);
  ReadOptions options;
  options.read_positions = true;
  ReadResult r = read_gbuffer(path.string(), options);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.info.positions_missing);
  EXPECT_TRUE(r.gbuffer.position_view.empty());
  EXPECT_TRUE(r.gbuffer.normal_missing.empty());  // every normal usable
  complete_gbuffer(r, 2);
  ASSERT_TRUE(r.ok()) << r.error;
  cv::Mat expected;
  view_positions_from_depth(r.gbuffer.depth_view, r.gbuffer.mask, r.gbuffer.camera, expected, {}, 1);
  EXPECT_TRUE(same_bits(r.gbuffer.position_view, expected));
  ASSERT_FALSE(r.info.uses.empty());
  EXPECT_EQ(r.info.uses.back().input, "position");
  EXPECT_EQ(r.info.uses.back().channels, "computed from depth");
  EXPECT_EQ(r.info.uses.back().space, "view");
}

TEST(CompleteGBuffer, FailedReadIsLeftAsItIs) {
  ReadResult r = read_gbuffer("/nonexistent/folder/frame.exr");
  ASSERT_FALSE(r.ok());
  const std::string error = r.error;
  complete_gbuffer(r, 1);
  EXPECT_EQ(r.error, error);
  EXPECT_TRUE(r.gbuffer.normal_view.empty());
}

}  // namespace
}  // namespace ssdo
