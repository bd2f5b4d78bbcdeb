// Temporal filtering (kernels/temporal.h) on a synthetic shot of the reference ray caster
// (tests/support/raycast.h: the camera trucks sideways past boxes, slabs and poles), where
// the exact AO is known: the denoised AO of gtao medium with the recommended K must flicker
// at most half as much as the frames computed alone (flicker: the reprojected
// frame-to-frame change over the surfaces both frames see whose exact AO changes by less
// than 0.05, kernels/metrics.h), with a mean error no worse.
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "service/frame_options.h"
#include "temporal_shot.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

constexpr int kFrames = raycast::kTruckShotFrames;
constexpr int kWidth = 192, kHeight = 108;
constexpr float kRadiusWorld = 1.0f;
constexpr int kReferenceRays = 128;  // as tests/accuracy/sequence_accuracy_test.cpp
constexpr uint32_t kReferenceSeed = 11;

struct Shot {
  std::vector<GBuffer> frames;
  std::vector<cv::Mat> references;  // ray-traced AO, CV_32FC1
  std::vector<const GBuffer*> pointers() const {
    std::vector<const GBuffer*> p;
    for (const GBuffer& g : frames) p.push_back(&g);
    return p;
  }
};

const Shot& shot() {
  static const Shot s = [] {
    Shot s;
    const raycast::Scene scene = raycast::truck_shot_scene();
    for (int t = 0; t < kFrames; ++t) {
      s.frames.push_back(raycast::render_gbuffer(scene, raycast::truck_shot_camera(t, kWidth, kHeight)));
      s.references.push_back(raycast::reference_ao(scene, s.frames.back(), kRadiusWorld, kReferenceRays, kReferenceSeed));
    }
    return s;
  }();
  return s;
}

FrameRequest request(AoMethod method, Preset preset, bool with_ssdo) {
  FrameRequest r;
  r.ao = ao_preset(method, preset);
  r.ao.radius_world = kRadiusWorld;
  r.ssdo.radius_world = kRadiusWorld;
  r.terms.ssdo = with_ssdo;
  r.terms.composite = false;
  return r;
}

TEST(TemporalAccuracy, SyntheticPanFlickersLessAndIsNoWorse) {
  const Shot& s = shot();
  const std::vector<const GBuffer*> frames = s.pointers();
  std::printf("| preset | K | term | flicker | reference flicker | MAE | ms raw | ms finish |\n");
  for (const Preset preset : {Preset::low, Preset::medium}) {
    const FrameRequest r = request(AoMethod::gtao, preset, preset == Preset::medium);
    double ms_raw = 0;
    const std::vector<RawFrame> raws = shot::raw_frames(frames, r, ms_raw);
    shot::TemporalMeasured alone_ao, alone_direct;
    for (int k = 0; k <= 3; ++k) {
      double ms_finish = 0;
      const std::vector<ComputedFrame> out = shot::finished_frames(raws, k, r, ms_finish);
      for (const char* term : {"ao_denoised", "ssdo_direct_denoised"}) {
        if (out[0].find(term) == nullptr) continue;
        const shot::TemporalMeasured m = shot::measure_shot(out, frames, s.references, term);
        std::printf("| %s | %d | %s | %.4f | %.4f | %.4f | %.0f | %.0f |\n", std::string(to_string(preset)).c_str(), k,
                    term, m.flicker, m.reference_flicker, m.mae, ms_raw, ms_finish);
        const bool ao = std::string(term) == "ao_denoised";
        if (k == 0) (ao ? alone_ao : alone_direct) = m;
        if (k != kRecommendedTemporalPerSide || preset != Preset::medium) continue;
        const shot::TemporalMeasured& alone = ao ? alone_ao : alone_direct;
        EXPECT_LE(m.flicker, 0.5 * alone.flicker) << term;
        if (ao) {
          EXPECT_LE(m.mae, alone.mae) << term;  // the light terms have no exact reference here
        }
      }
    }
  }
}

}  // namespace
}  // namespace ssdo
