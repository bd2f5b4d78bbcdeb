// The confidence output (kernels/confidence.h) against the real error on the shared Cycles
// dumps (cornell, greeble, depthgap; 640x360, ray-traced AO within the frame's AO
// distance): over the three frames, the pixels with confidence < 0.5 must have a clearly
// larger mean |AO - Cycles AO| than those with confidence > 0.9, for every method (high
// preset, raw output as the pipeline writes "ao"). And the pipeline writes the term.
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "formats/gbuffer_reader.h"
#include "kernels/half_resolution.h"
#include "service/frame_inputs.h"
#include "kernels/ao.h"
#include "kernels/confidence.h"
#include "kernels/positions.h"
#include "service/pipeline.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

struct Split {
  double sum_low = 0, sum_high = 0;
  int64_t n_low = 0, n_high = 0, n = 0;
};

TEST(ConfidenceIntegration, CorrelatesWithErrorOnSharedFrames) {
  const fs::path dir = fs::path(SSDO_SHARED_DIR) / "gbuffers";
  if (!fs::exists(dir / "cornell.exr")) GTEST_SKIP() << "no shared frames at " << dir;
  const AoMethod methods[] = {AoMethod::hemisphere, AoMethod::hbao, AoMethod::gtao};
  Split split[3];
  Split per_frame[3][3];
  const char* frames[] = {"cornell", "greeble", "depthgap"};
  for (int fi = 0; fi < 3; ++fi) {
    ReadOptions options;
    options.read_references = true;
    ReadResult r = read_frame((dir / (std::string(frames[fi]) + ".exr")).string(), options);
    ASSERT_TRUE(r.ok()) << r.error;
    const GBuffer& g = r.gbuffer;
    cv::Mat reference = g.references.at("AO");
    if (reference.channels() != 1) cv::extractChannel(reference, reference, 0);
    cv::Mat position_view;
    view_positions_from_depth(g.depth_view, g.mask, g.camera, position_view);
    const float radius = r.info.ao_distance_world ? *r.info.ao_distance_world : 1.0f;
    for (int mi = 0; mi < 3; ++mi) {
      AoSettings s = ao_preset(methods[mi], Preset::high);
      s.radius_world = radius;
      const AoInputs in{g.depth_view, g.normal_view, position_view, g.mask, g.camera};
      AoOutput out;
      compute_ao_at_resolution(in, s, out);
      ConfidenceSettings cs;
      cs.radius_world = s.radius_world;
      cs.max_radius_px = s.max_radius_px;
      cv::Mat confidence;
      compute_confidence_at_resolution(g.depth_view, g.normal_view, g.mask, g.camera, cs, confidence);
      for (int y = 0; y < g.mask.rows; ++y)
        for (int x = 0; x < g.mask.cols; ++x) {
          if (!g.mask.at<uint8_t>(y, x)) continue;
          const double e = std::abs(double(out.ao.at<float>(y, x)) - reference.at<float>(y, x));
          const float c = confidence.at<float>(y, x);
          for (Split* sp : {&split[mi], &per_frame[mi][fi]}) {
            ++sp->n;
            if (c < 0.5f) sp->sum_low += e, ++sp->n_low;
            if (c > 0.9f) sp->sum_high += e, ++sp->n_high;
          }
        }
    }
  }
  std::printf("mean |AO - Cycles| by confidence, high presets: conf<0.5 | conf>0.9 (pixels)\n");
  for (int mi = 0; mi < 3; ++mi) {
    const Split& sp = split[mi];
    const double low = sp.sum_low / double(std::max<int64_t>(sp.n_low, 1));
    const double high = sp.sum_high / double(std::max<int64_t>(sp.n_high, 1));
    std::printf("  %-10s all frames %.3f (%lld) | %.3f (%lld) of %lld\n",
                std::string(to_string(methods[mi])).c_str(), low, (long long)sp.n_low, high,
                (long long)sp.n_high, (long long)sp.n);
    for (int fi = 0; fi < 3; ++fi) {
      const Split& f = per_frame[mi][fi];
      std::printf("    %-9s %.3f (%lld) | %.3f (%lld)\n", frames[fi],
                  f.sum_low / double(std::max<int64_t>(f.n_low, 1)), (long long)f.n_low,
                  f.sum_high / double(std::max<int64_t>(f.n_high, 1)), (long long)f.n_high);
    }
    EXPECT_GT(sp.n_low, 1000);
    EXPECT_GT(low, 1.5 * high) << to_string(methods[mi]);
  }
}

TEST(ConfidenceIntegration, PipelineWritesConfidenceWithAoAndSsdo) {
  const fs::path dir = fs::path(SSDO_SHARED_DIR) / "gbuffers";
  if (!fs::exists(dir / "depthgap.exr")) GTEST_SKIP() << "no shared frames at " << dir;
  ReadResult r = read_frame((dir / "depthgap.exr").string());
  ASSERT_TRUE(r.ok()) << r.error;
  for (const char* terms : {"ao", "ssdo"}) {
    FrameRequest request;
    std::string error;
    ASSERT_TRUE(parse_terms(terms, request.terms, error)) << error;
    request.ao = ao_preset(AoMethod::gtao, Preset::low);
    const ComputedFrame frame = compute_frame(r.gbuffer, request);
    const cv::Mat* c = frame.find("confidence");
    ASSERT_NE(c, nullptr) << terms;
    EXPECT_EQ(c->type(), CV_16FC1) << "stored in half, as the output writes it";
    cv::Mat values;
    c->convertTo(values, CV_32F);
    double lo, hi;
    cv::minMaxLoc(values, &lo, &hi);
    EXPECT_GE(lo, 0.0);
    EXPECT_LE(hi, 1.0);
    EXPECT_LT(lo, 0.5) << "a frame with depth gaps and borders has unobserved neighbourhoods";
  }
}

}  // namespace
}  // namespace ssdo
