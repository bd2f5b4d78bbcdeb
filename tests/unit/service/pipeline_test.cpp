// The pipeline's read narrowing (reads_for, view_reads_for), the I/O floor's stand-in terms
// (io_only_frame) against compute_frame, compute_frame consuming its G-buffer, and the
// denoise's footprint per grid.
#include "service/pipeline.h"
#include "tests/support/image_difference.h"

#include <set>
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

// The names of the outputs' channels and previews (NAME.ssdo.<term>.png): part of the
// output format, the same whatever names the code gives them.
TEST(OutputTermNames, AreTheOutputsChannelNames) {
  EXPECT_EQ(output_term_names(),
            (std::vector<std::string>{"ao", "ao_denoised", "bent_normal", "confidence", "composite", "ssdo_direct",
                                      "ssdo_direct_denoised", "ssdo_indirect", "ssdo_indirect_denoised"}));
}

TEST(IoOnlyFrame, SameTermsAsComputeFrame) {
  const GBuffer g = small_frame();
  std::set<std::string> written;  // every name compute_frame wrote, over all the requests
  for (const char* terms : {"ao", "ssdo", "composite", "ao,ssdo", "all"})
    for (AoMethod method : {AoMethod::gtao, AoMethod::hbao, AoMethod::hemisphere}) {
      FrameRequest r = request_for(terms);
      r.ao = ao_preset(method, Preset::low);
      r.threads = 1;
      const ComputedFrame computed = compute_frame(g, r);
      const ComputedFrame standin = io_only_frame(g, r);
      ASSERT_EQ(standin.terms.size(), computed.terms.size()) << terms << " " << to_string(method);
      for (const OutputTerm& c : computed.terms) {  // the names a failed frame's previews are removed by
        EXPECT_NE(std::find(output_term_names().begin(), output_term_names().end(), c.name), output_term_names().end())
            << c.name;
        written.insert(c.name);
      }
      for (size_t i = 0; i < computed.terms.size(); ++i) {
        const OutputTerm &c = computed.terms[i], &s = standin.terms[i];
        EXPECT_EQ(s.name, c.name) << terms;
        EXPECT_EQ(s.type, c.type) << c.name;
        EXPECT_EQ(s.vector, c.vector) << c.name;
        EXPECT_EQ(s.image.type(), c.image.type()) << c.name;
        EXPECT_EQ(s.image.size(), c.image.size()) << c.name;
      }
    }
  // ... and each name of the list is one compute_frame writes.
  EXPECT_EQ(written, std::set<std::string>(output_term_names().begin(), output_term_names().end()));
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
      EXPECT_EQ(test::max_difference(released.terms[i].image, kept.terms[i].image), 0.0)
          << terms << " " << kept.terms[i].name;
    }
  }
}

// The frame's term `name` (a test failure and an empty image when it has none).
const cv::Mat& term(const ComputedFrame& frame, const std::string& name) {
  static const cv::Mat none;
  const cv::Mat* m = frame.find(name);
  EXPECT_NE(m, nullptr) << "no term " << name;
  return m ? *m : none;
}

// AO on the full grid (gtao high), SSDO on the half grid (low), one thread.
FrameRequest mixed_grids_request() {
  FrameRequest r = request_for("ao,ssdo");
  r.ao = ao_preset(AoMethod::gtao, Preset::high);
  r.threads = 1;
  EXPECT_FALSE(runs_on_half_grid(r.ao));
  EXPECT_TRUE(runs_on_half_grid(r.ssdo));
  return r;
}

// Each denoised term is its raw term blurred on the grid it was computed on: AO at full
// resolution (high) with the settings as given (scaled_to_grid of divisor 1), SSDO on the
// half grid (low) there, before the upsample (compute_terms with TermSettings::denoise).
// A frame in two steps (compute_raw_frame, then finish_frame, the path of a shot's frames,
// here without neighbours) gives the bits of compute_frame for every term.
TEST(ComputeFrame, DenoisedTermsUseTheGridTheyWereComputedOn) {
  const GBuffer g = small_frame();
  const FrameRequest r = mixed_grids_request();
  const ComputedFrame finished = finish_frame(compute_raw_frame(GBuffer(g), r), {}, r);
  const ComputedFrame lone = compute_frame(g, r);
  cv::Mat ao_denoised;
  denoise_bilateral(term(lone, "ao"), g.depth_view, g.normal_view, g.mask, scaled_to_grid(r.denoise, 1), ao_denoised, {},
                    1);
  EXPECT_EQ(cv::norm(term(lone, "ao_denoised"), ao_denoised, cv::NORM_INF), 0.0);

  const Environment white;
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &white, &g.albedo,
                      &g.lighting};
  TermOutputs on_grid;
  compute_terms(in, {nullptr, &r.ssdo, nullptr, &r.denoise}, on_grid, {}, 1);
  EXPECT_EQ(cv::norm(term(lone, "ssdo_direct_denoised"), on_grid.denoised.direct, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(term(lone, "ssdo_indirect_denoised"), on_grid.denoised.indirect, cv::NORM_INF), 0.0);
  // The raw SSDO terms are kept in half (nothing but the output reads them).
  ASSERT_EQ(term(lone, "ssdo_direct").type(), CV_16FC3);
  cv::Mat raw_in_half;
  on_grid.ssdo.direct.convertTo(raw_in_half, CV_16F);
  EXPECT_EQ(test::max_difference(term(lone, "ssdo_direct"), raw_in_half), 0.0);

  ASSERT_EQ(finished.terms.size(), lone.terms.size());
  for (size_t i = 0; i < lone.terms.size(); ++i) {
    EXPECT_EQ(finished.terms[i].name, lone.terms[i].name);
    EXPECT_EQ(finished.terms[i].image.type(), lone.terms[i].image.type()) << lone.terms[i].name;
    EXPECT_EQ(test::max_difference(finished.terms[i].image, lone.terms[i].image), 0.0) << lone.terms[i].name;
  }
}

// A shot's frame whose AO runs on the full grid (high) and SSDO on the half grid (low): each
// term is filtered over the neighbour's same term on the grid it was computed on, from what
// temporal_part keeps of the neighbour. The neighbour here is the same view with other noise
// (another seed): the raw terms stay the frame's own, the denoised ones move.
TEST(FinishFrame, EachTermIsFilteredOverTimeOnItsOwnGrid) {
  const GBuffer g = small_frame();
  const FrameRequest r = mixed_grids_request();
  FrameRequest other_noise = r;
  other_noise.ao.seed = 7;
  other_noise.ssdo.seed = 7;
  const RawFrame neighbour = temporal_part(compute_raw_frame(GBuffer(g), other_noise));
  EXPECT_TRUE(neighbour.raw.ssdo.direct.empty()) << "a half grid's terms are kept on the grid";
  EXPECT_FALSE(neighbour.raw.grid.direct.empty());
  EXPECT_FALSE(neighbour.raw.ao.ao.empty());
  const RawFrame* neighbours[] = {&neighbour};
  const ComputedFrame filtered = finish_frame(compute_raw_frame(GBuffer(g), r), neighbours, r);
  const ComputedFrame alone = compute_frame(g, r);
  ASSERT_EQ(filtered.temporal.size(), 1u);
  EXPECT_TRUE(filtered.temporal[0].used);
  for (const std::string name : {"ao", "ssdo_direct", "ssdo_indirect"})
    EXPECT_EQ(test::max_difference(term(filtered, name), term(alone, name)), 0.0) << name;
  for (const std::string name : {"ao_denoised", "ssdo_direct_denoised"})
    EXPECT_GT(test::max_difference(term(filtered, name), term(alone, name)), 1e-4) << name;
}

}  // namespace
}  // namespace ssdo
