// The pipeline's read narrowing (reads_for, view_reads_for), the I/O floor's stand-in terms
// (io_only_frame) against compute_frame, compute_frame consuming its G-buffer, and the
// denoise's footprint per grid.
#include "service/pipeline.h"

#include <string>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

FrameRequest request_for(const std::string& terms) {
  FrameRequest r;
  std::string error;
  EXPECT_TRUE(parse_terms(terms, r.terms, error)) << error;
  r.ao = ao_preset(AoMethod::gtao, Preset::low);
  r.ssdo = ssdo_preset(SsdoMethod::ssdo, Preset::low);
  return r;
}

TEST(ReadsFor, OnlyTheInputsTheTermsUse) {
  ReadOptions read = reads_for(request_for("ao"));
  EXPECT_FALSE(read.read_lighting);
  EXPECT_FALSE(read.read_albedo);
  EXPECT_FALSE(read.read_references);
  FrameRequest multibounce = request_for("ao");
  multibounce.ao.multibounce = true;
  EXPECT_TRUE(reads_for(multibounce).read_albedo);
  read = reads_for(request_for("ao,ssdo"));
  EXPECT_TRUE(read.read_lighting);
  EXPECT_TRUE(read.read_albedo);
  EXPECT_FALSE(read.read_references);
  read = reads_for(request_for("ao,composite"));
  EXPECT_TRUE(read.read_albedo);
  EXPECT_FALSE(read.read_references);  // no mapped Env pass
  FrameRequest env = request_for("ao,composite");
  env.read.mapping.references["Env"] = "ViewLayer.Env";
  EXPECT_TRUE(reads_for(env).read_references);
  // What the caller turned off stays off.
  FrameRequest off = request_for("ssdo");
  off.read.read_lighting = false;
  EXPECT_FALSE(reads_for(off).read_lighting);
  EXPECT_FALSE(reads_for(request_for("ssdo")).read_references);
}

// Neighbours read as views: depth, plus the light of SSDO's senders as the kernels read it
// on the frame: the lighting when the frame has its own, else the albedo (and the albedo for
// multi-bounce AO).
TEST(ReadsFor, ViewsBringTheirLightOnlyToSsdo) {
  for (const std::string terms : {"ao", "ao,composite"})
    for (const bool lit : {false, true}) {
      const FrameRequest r = request_for(terms);
      const ReadOptions view = view_reads_for(r, reads_for(r), lit);
      EXPECT_FALSE(view.read_albedo) << terms;
      EXPECT_FALSE(view.read_lighting) << terms;
      EXPECT_FALSE(view.read_normals) << terms;
    }
  const FrameRequest ssdo = request_for("ao,ssdo");
  const ReadOptions lit = view_reads_for(ssdo, reads_for(ssdo), true);
  EXPECT_FALSE(lit.read_albedo);  // the senders' light is the lighting
  EXPECT_TRUE(lit.read_lighting);
  EXPECT_FALSE(lit.read_normals);
  EXPECT_FALSE(lit.read_positions);
  EXPECT_FALSE(lit.read_references);
  const ReadOptions unlit = view_reads_for(ssdo, reads_for(ssdo), false);
  EXPECT_TRUE(unlit.read_albedo);  // the senders' light is their direct light times the albedo
  EXPECT_FALSE(unlit.read_lighting);
  FrameRequest multibounce = ssdo;
  multibounce.ao.multibounce = true;
  EXPECT_TRUE(view_reads_for(multibounce, reads_for(multibounce), true).read_albedo);
  EXPECT_TRUE(view_reads_for(multibounce, reads_for(multibounce), true).read_lighting);
  // What the frame does not read, its views do not either.
  FrameRequest no_lighting = request_for("ssdo");
  no_lighting.read.read_lighting = false;
  EXPECT_FALSE(view_reads_for(no_lighting, reads_for(no_lighting), true).read_lighting);
  EXPECT_TRUE(view_reads_for(no_lighting, reads_for(no_lighting), true).read_albedo);
}

// A small synthetic frame: a tilted plane with a box on it.
GBuffer small_frame() {
  GBuffer g;
  const int w = 48, h = 32;
  g.camera = Camera::from_fov_x(w, h, 60.0f, 0.1f, 100.0f);
  g.depth_view.create(h, w, CV_32FC1);
  g.normal_view.create(h, w, CV_32FC3);
  g.mask = cv::Mat(h, w, CV_8UC1, cv::Scalar(255));
  g.albedo = cv::Mat(h, w, CV_32FC3, cv::Scalar(0.5f, 0.6f, 0.7f));
  g.lighting = cv::Mat(h, w, CV_32FC3, cv::Scalar(0.2f, 0.2f, 0.2f));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool box = x > 18 && x < 30 && y > 12 && y < 24;
      g.depth_view.at<float>(y, x) = box ? 4.0f : 5.0f + 0.05f * float(y);
      g.normal_view.at<cv::Vec3f>(y, x) = box ? cv::Vec3f(0, 0, 1) : cv::Vec3f(0, 0.3f, 0.954f);
    }
  return g;
}

TEST(IoOnlyFrame, SameTermsAsComputeFrame) {
  const GBuffer g = small_frame();
  for (const char* terms : {"ao", "ssdo", "composite", "ao,ssdo", "all"})
    for (AoMethod method : {AoMethod::gtao, AoMethod::hbao, AoMethod::hemisphere}) {
      FrameRequest r = request_for(terms);
      r.ao = ao_preset(method, Preset::low);
      r.threads = 1;
      const ComputedFrame computed = compute_frame(g, r);
      const ComputedFrame standin = io_only_frame(g, r);
      ASSERT_EQ(standin.terms.size(), computed.terms.size()) << terms << " " << to_string(method);
      for (size_t i = 0; i < computed.terms.size(); ++i) {
        const OutputTerm &c = computed.terms[i], &s = standin.terms[i];
        EXPECT_EQ(s.name, c.name) << terms;
        EXPECT_EQ(s.type, c.type) << c.name;
        EXPECT_EQ(s.vector, c.vector) << c.name;
        EXPECT_EQ(s.image.type(), c.image.type()) << c.name;
        EXPECT_EQ(s.image.size(), c.image.size()) << c.name;
      }
    }
}

// The consuming compute_frame returns the bits of the one that leaves the G-buffer alone,
// and releases the images no later step reads (depth and normals; the albedo without a
// composite, the lighting unless the composite adds it) while keeping the ones the
// composite reads.
TEST(ComputeFrame, ConsumingTheGBufferGivesTheSameTerms) {
  const GBuffer g = small_frame();
  ASSERT_FALSE(g.albedo.empty());
  ASSERT_FALSE(g.lighting.empty());
  FrameRequest adds_lighting = request_for("all");
  adds_lighting.composite_terms = {{CompositeTerm::ssdo_direct, 1.0f}, {CompositeTerm::lighting, 1.0f}};
  for (const char* terms : {"ao", "ssdo", "ao,ssdo", "all", "all+lighting"}) {
    const bool composite_adds_lighting = std::string(terms) == "all+lighting";
    FrameRequest r = composite_adds_lighting ? adds_lighting : request_for(terms);
    r.threads = 2;
    const ComputedFrame kept = compute_frame(g, r);
    EXPECT_FALSE(g.depth_view.empty());
    GBuffer consumed = small_frame();
    const ComputedFrame released = compute_frame(std::move(consumed), r);
    EXPECT_TRUE(consumed.depth_view.empty()) << terms;
    EXPECT_TRUE(consumed.normal_view.empty()) << terms;
    EXPECT_EQ(consumed.albedo.empty(), !r.terms.composite) << terms;
    EXPECT_EQ(consumed.lighting.empty(), !composite_adds_lighting) << terms;
    ASSERT_EQ(released.terms.size(), kept.terms.size()) << terms;
    for (size_t i = 0; i < kept.terms.size(); ++i) {
      EXPECT_EQ(released.terms[i].name, kept.terms[i].name);
      EXPECT_EQ(cv::norm(released.terms[i].image, kept.terms[i].image, cv::NORM_INF), 0.0)
          << terms << " " << kept.terms[i].name;
    }
  }
}

// Each denoised term of a frame finished at full resolution (finish_frame, the temporal
// path, here without neighbours) is its raw term blurred with the footprint of the grid it
// was computed on (scaled_to_grid): AO at full resolution (high) with the settings as
// given, SSDO on the half grid (low) with twice the radius; and the scaling shows (the
// plain settings give other bits). compute_frame, for a lone frame, denoises the terms on
// the half grid there (compute_terms with TermSettings::denoise): AO on the full grid as
// before, SSDO with the bits of compute_terms' denoised terms.
TEST(ComputeFrame, DenoisedTermsUseTheFootprintOfTheirGrid) {
  const GBuffer g = small_frame();
  FrameRequest r = request_for("ao,ssdo");
  r.ao = ao_preset(AoMethod::gtao, Preset::high);
  r.threads = 1;
  ASSERT_FALSE(runs_on_half_grid(r.ao));
  ASSERT_TRUE(runs_on_half_grid(r.ssdo));
  const ComputedFrame finished = finish_frame(compute_raw_frame(GBuffer(g), r), {}, r);
  const ComputedFrame lone = compute_frame(g, r);
  auto term = [&](const ComputedFrame& frame, const std::string& name) -> const cv::Mat& {
    if (const cv::Mat* m = frame.find(name)) return *m;
    ADD_FAILURE() << "no term " << name;
    static const cv::Mat none;
    return none;
  };
  auto denoised = [&](const std::string& raw, const DenoiseSettings& s) {
    cv::Mat out;
    denoise_bilateral(term(finished, raw), g.depth_view, g.normal_view, g.mask, s, out, {}, 1);
    return out;
  };
  EXPECT_EQ(cv::norm(term(finished, "ao_denoised"), denoised("ao", scaled_to_grid(r.denoise, 1)), cv::NORM_INF), 0.0);
  for (const std::string name : {"ssdo_direct", "ssdo_indirect"})
    EXPECT_EQ(cv::norm(term(finished, name + "_denoised"), denoised(name, scaled_to_grid(r.denoise, 2)), cv::NORM_INF),
              0.0)
        << name;
  // (The small frame's bounce is too faint to tell the footprints apart; its direct light is not.)
  EXPECT_GT(cv::norm(term(finished, "ssdo_direct_denoised"), denoised("ssdo_direct", r.denoise), cv::NORM_INF), 1e-4);

  // The lone frame: the same raw terms (SSDO's kept in half: nothing but the output reads
  // them); AO denoised as above; SSDO denoised on its grid.
  auto values = [](const cv::Mat& m) {  // rounded to half as the output stores it, as floats
    cv::Mat in_half = m, out;
    if (m.depth() != CV_16F) m.convertTo(in_half, CV_16F);
    in_half.convertTo(out, CV_32F);
    return out;
  };
  for (const std::string name : {"ao", "ao_denoised"})
    EXPECT_EQ(cv::norm(term(lone, name), term(finished, name), cv::NORM_INF), 0.0) << name;
  for (const std::string name : {"ssdo_direct", "ssdo_indirect"}) {
    ASSERT_EQ(term(lone, name).type(), CV_16FC3) << name;
    EXPECT_EQ(cv::norm(values(term(lone, name)), values(term(finished, name)), cv::NORM_INF), 0.0) << name;
  }
  const Environment white;
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &white, &g.albedo,
                      &g.lighting};
  TermOutputs on_grid;
  compute_terms(in, {nullptr, &r.ssdo, nullptr, &r.denoise}, on_grid, {}, 1);
  EXPECT_EQ(cv::norm(term(lone, "ssdo_direct_denoised"), on_grid.denoised.direct, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(term(lone, "ssdo_indirect_denoised"), on_grid.denoised.indirect, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(term(lone, "ssdo_direct_denoised"), term(finished, "ssdo_direct_denoised"), cv::NORM_INF), 1e-5);
}

}  // namespace
}  // namespace ssdo
