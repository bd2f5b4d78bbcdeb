#include "service/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <sstream>

#include "core/parallel.h"
#include "core/half_samples.h"
#include "kernels/confidence.h"
#include "kernels/half_resolution.h"
#include "service/frame_inputs.h"
#include "service/guard_band.h"

namespace ssdo {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

bool parse_terms(const std::string& list, TermSelection& terms, std::string& error) {
  TermSelection t{false, false, false};
  std::stringstream ss(list);
  std::string item;
  bool any = false;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    any = true;
    if (item == "ao") t.ao = true;
    else if (item == "ssdo") t.ssdo = true;
    else if (item == "composite") t.composite = true;
    else if (item == "all") t = {true, true, true};
    else {
      error = "unknown term '" + item + "' (terms: ao, ssdo, composite, all)";
      return false;
    }
  }
  if (!any) {
    error = "no term selected (terms: ao, ssdo, composite, all)";
    return false;
  }
  // SSDO is light: selecting it also writes the image it lights (the composite).
  if (t.ssdo) t.composite = true;
  terms = t;
  return true;
}

std::string to_string(const TermSelection& terms) {
  std::string s;
  auto add = [&](bool on, const char* name) {
    if (!on) return;
    if (!s.empty()) s += ",";
    s += name;
  };
  add(terms.ao, "ao");
  add(terms.ssdo, "ssdo");
  add(terms.composite, "composite");
  return s;
}

const cv::Mat* ComputedFrame::find(const std::string& name) const {
  for (const OutputTerm& t : terms)
    if (t.name == name) return &t.image;
  return nullptr;
}

namespace {

// Which of the selected terms compute_frame computes (the composite may pull in terms that
// are not written).
struct TermsComputed {
  bool ao = false, ssdo = false;
  std::vector<WeightedTerm> composite_terms;
};

TermsComputed terms_computed(const FrameRequest& request) {
  const TermSelection& terms = request.terms;
  TermsComputed c;
  c.composite_terms = !request.composite_terms.empty() ? request.composite_terms
                      : terms.ssdo ? composite_mode_terms(CompositeMode::ssdo)
                                   : composite_mode_terms(CompositeMode::ssao);
  auto composite_uses = [&](CompositeTerm t) {
    if (!terms.composite) return false;
    for (const WeightedTerm& w : c.composite_terms)
      if (w.term == t) return true;
    return false;
  };
  c.ao = terms.ao || composite_uses(CompositeTerm::ambient_ao);
  c.ssdo = terms.ssdo || composite_uses(CompositeTerm::ssdo_direct) ||
           composite_uses(CompositeTerm::ssdo_indirect);
  return c;
}

}  // namespace

ComputedFrame compute_frame(const GBuffer& gbuffer, const FrameRequest& request) {
  GBuffer shared = gbuffer;  // the images' headers: releasing them frees nothing of the caller's
  return compute_frame(std::move(shared), request);
}

namespace {

const Environment& frame_environment(const FrameRequest& request) {
  static const Environment kWhite;  // constant radiance 1
  return request.environment ? *request.environment : kWhite;
}

// The confidence measures the neighbourhood of the AO radius, else SSDO's.
ConfidenceSettings confidence_settings(const FrameRequest& request) {
  ConfidenceSettings cs;
  cs.radius_world = request.terms.ao ? request.ao.radius_world : request.ssdo.radius_world;
  cs.max_radius_px = request.terms.ao ? request.ao.max_radius_px : request.ssdo.max_radius_px;
  cs.depth_bias_relative = request.ao.depth_bias_relative;
  return cs;
}

// The temporal filter's settings: the request's, with the reach of the terms it filters
// (TemporalSettings::radius_world): the larger of the AO and SSDO radii and pixel bounds
// (one radius for both, resolve_frame_radius, unless set apart), the bound in pixels of the
// grid filtered (max_radius_on_grid: on the half grid its texels, as the kernels' there).
TemporalSettings temporal_settings(const FrameRequest& request, int resolution_divisor) {
  TemporalSettings s = request.temporal;
  s.radius_world = std::max(request.ao.radius_world, request.ssdo.radius_world);
  s.max_radius_px =
      max_radius_on_grid(std::max(request.ao.max_radius_px, request.ssdo.max_radius_px), resolution_divisor);
  return s;
}

// The terms a frame keeps in half float as the kernels' upsample writes them, because
// nothing but the half-float output reads them: the bent normal, the confidence, and the
// raw AO and SSDO terms of the half grid (the denoise and a shot's filter over time read
// them on the grid; the composite reads the denoised ones). io_only_frame's stand-ins have
// the same types.
constexpr HalfOutputs kOutputsInHalf{.bent_normal = true, .ssdo = true, .ao = true, .confidence = true};

// AO, SSDO and the confidence, each at the resolution its settings ask: the kernels that
// run at half resolution share one grid and one upsample (kernels/half_resolution.h).
// confidence: the observed fraction of the neighbourhood the AO (else SSDO) radius
// samples (kernels/confidence.h), written with every AO or SSDO output. denoise_on_grid:
// the terms on the half grid are also denoised there (TermOutputs::denoised), for a frame
// whose raw terms are not filtered over time first; else the grid and its raw terms are kept
// (TermOutputs::grid) for finish_frame, which filters them over time there.
TermOutputs compute_raw_terms(const GBuffer& g, const FrameRequest& request, const TermsComputed& computed,
                              bool denoise_on_grid, const std::function<void()>& inputs_read) {
  const bool confidence_wanted = request.terms.ao || request.terms.ssdo;
  const ConfidenceSettings confidence = confidence_settings(request);
  const TermInputs in{g.depth_view, g.normal_view, g.position_view, g.mask, g.camera, &frame_environment(request),
                      g.has_albedo() ? &g.albedo : nullptr, g.lighting.empty() ? nullptr : &g.lighting,
                      g.depth_back_view.empty() ? nullptr : &g.depth_back_view, g.views, g.data_origin_px};
  TermSettings selected{computed.ao ? &request.ao : nullptr, computed.ssdo ? &request.ssdo : nullptr,
                        confidence_wanted ? &confidence : nullptr, denoise_on_grid ? &request.denoise : nullptr};
  selected.stored_in_half = kOutputsInHalf;
  selected.keep_grid_terms = !denoise_on_grid;
  TermOutputs out;
  compute_terms(in, selected, out, {}, request.threads, inputs_read);
  return out;
}

// The raw terms the denoise reads, in the order of DenoisedTerms (those computed).
std::vector<const cv::Mat*> raw_terms(const TermOutputs& raw, const TermsComputed& computed) {
  std::vector<const cv::Mat*> terms;
  if (computed.ao) terms.push_back(&raw.ao.ao);
  if (computed.ssdo) terms.push_back(&raw.ssdo.direct), terms.push_back(&raw.ssdo.indirect);
  return terms;
}

std::vector<cv::Mat*> term_slots(DenoisedTerms& d, const TermsComputed& computed) {
  std::vector<cv::Mat*> slots;
  if (computed.ao) slots.push_back(&d.ao);
  if (computed.ssdo) slots.push_back(&d.direct), slots.push_back(&d.indirect);
  return slots;
}

// The divisor of the grid each raw term was computed on (1 or 2), in raw_terms' order.
std::vector<int> term_grids(const FrameRequest& request, const TermsComputed& computed) {
  std::vector<int> grids;
  if (computed.ao) grids.push_back(runs_on_half_grid(request.ao) ? 2 : 1);
  if (computed.ssdo) grids.insert(grids.end(), 2, runs_on_half_grid(request.ssdo) ? 2 : 1);
  return grids;
}

// The entries of `all` (in raw_terms' order) whose term was computed on the full grid.
template <typename T>
std::vector<T> on_full_grid(const std::vector<T>& all, const FrameRequest& request, const TermsComputed& computed) {
  const std::vector<int> grids = term_grids(request, computed);
  std::vector<T> kept;
  for (size_t i = 0; i < all.size(); ++i)
    if (grids[i] == 1) kept.push_back(all[i]);
  return kept;
}

// The raw terms computed on the full grid filtered over the neighbours' (kernels/temporal.h)
// at full resolution, into `filtered`; uses: what each neighbour contributed. Without
// neighbours or such terms nothing is written.
void filter_over_time(const GBuffer& g, const TermOutputs& raw, std::span<const RawFrame* const> neighbours,
                      const FrameRequest& request, const TermsComputed& computed, DenoisedTerms& filtered,
                      std::vector<TemporalUse>& uses) {
  const std::vector<const cv::Mat*> terms = on_full_grid(raw_terms(raw, computed), request, computed);
  if (neighbours.empty() || terms.empty()) return;
  std::vector<std::vector<const cv::Mat*>> neighbour_terms;
  std::vector<TemporalFrame> frames;
  neighbour_terms.reserve(neighbours.size());
  for (const RawFrame* n : neighbours) {
    neighbour_terms.push_back(on_full_grid(raw_terms(n->raw, computed), request, computed));
    frames.push_back({n->gbuffer.camera, n->gbuffer.depth_view, n->gbuffer.normal_view, n->gbuffer.mask,
                      neighbour_terms.back()});
  }
  const std::vector<cv::Mat*> results = on_full_grid(term_slots(filtered, computed), request, computed);
  uses = filter_temporal({g.camera, g.depth_view, g.normal_view, g.mask, terms}, frames, temporal_settings(request, 1),
                         results, {}, request.threads);
}

// The terms of a grid (HalfGridTerms), AO then SSDO direct and indirect, those present.
std::vector<const cv::Mat*> grid_terms(const HalfGridTerms& t) {
  std::vector<const cv::Mat*> terms;
  if (!t.ao.empty()) terms.push_back(&t.ao);
  if (!t.direct.empty()) terms.push_back(&t.direct), terms.push_back(&t.indirect);
  return terms;
}

// The raw terms computed on the half grid filtered over the neighbours' on their own half
// grids (kernels/temporal.h: each grid's camera, guides and texels, a quarter of the pixels);
// uses: what each neighbour contributed. Without neighbours, the raw terms themselves.
HalfGridTerms filter_grid_over_time(const HalfGridTerms& own, std::span<const RawFrame* const> neighbours,
                                    const FrameRequest& request, std::vector<TemporalUse>& uses) {
  if (neighbours.empty()) return own;
  const std::vector<const cv::Mat*> terms = grid_terms(own);
  std::vector<std::vector<const cv::Mat*>> neighbour_terms;
  std::vector<TemporalFrame> frames;
  neighbour_terms.reserve(neighbours.size());
  for (const RawFrame* n : neighbours) {
    const HalfGridTerms& grid = n->raw.grid;
    neighbour_terms.push_back(grid_terms(grid));
    // The same request computes the same terms on the same grids in every frame.
    CV_Assert(neighbour_terms.back().size() == terms.size());
    frames.push_back({grid.grid.camera, grid.grid.depth_view, grid.grid.normal_view, grid.grid.mask,
                      neighbour_terms.back()});
  }
  HalfGridTerms filtered;
  filtered.grid = own.grid;
  std::vector<cv::Mat*> results;
  if (!own.ao.empty()) results.push_back(&filtered.ao);
  if (!own.direct.empty()) results.push_back(&filtered.direct), results.push_back(&filtered.indirect);
  const HalfGrid& h = own.grid;
  uses = filter_temporal({h.camera, h.depth_view, h.normal_view, h.mask, terms}, frames, temporal_settings(request, 2),
                         results, {}, request.threads);
  return filtered;
}

// The denoised terms of `sources` (raw_terms' order): those of `done` (the half grid's,
// denoised on the grid: compute_terms' TermSettings::denoise or finish_half_grid_terms) as
// they are, the others here at full resolution. Each term's footprint is scaled to the
// grid it was computed on (scaled_to_grid, kernels/denoise.h); terms of one grid are
// blurred in one pass over the frame, since the blur's weights depend only on the guides
// (AO and the two SSDO terms share them when they share a grid).
DenoisedTerms denoise_terms(const GBuffer& g, const FrameRequest& request, const std::vector<const cv::Mat*>& sources,
                            const TermsComputed& computed, DenoisedTerms done) {
  DenoisedTerms d = std::move(done);
  const std::vector<cv::Mat*> results = term_slots(d, computed);
  const std::vector<int> grids = term_grids(request, computed);
  for (const int grid : {1, 2}) {
    std::vector<const cv::Mat*> in;
    std::vector<cv::Mat*> out;
    for (size_t i = 0; i < sources.size(); ++i)
      if (grids[i] == grid && results[i]->empty()) in.push_back(sources[i]), out.push_back(results[i]);
    if (!in.empty())
      denoise_bilateral(in, g.depth_view, g.normal_view, g.mask, scaled_to_grid(request.denoise, grid), out, {},
                        request.threads);
  }
  return d;
}

// The written terms, in the output's channel order. Every term is stored in half float, as
// Cycles stores its own AO and light passes: AO and the confidence lie in [0, 1], where half
// keeps steps of at most 2^-11 (at 1, finer below), an eighth of an 8-bit display step,
// and drops the noisy low mantissa bits of float, which no lossless codec shrinks.
void add_output_terms(const FrameRequest& request, const TermsComputed& computed, const TermOutputs& raw,
                      const DenoisedTerms& d, ComputedFrame& frame) {
  const TermSelection& terms = request.terms;
  const auto add = [&](OutputTermId term, const cv::Mat& image, bool vector = false) {
    frame.terms.push_back({output_term_name(term), image, SampleType::half, vector});
  };
  if (computed.ao && terms.ao) {
    add(OutputTermId::ao, raw.ao.ao);
    add(OutputTermId::ao_denoised, d.ao);
    if (!raw.ao.bent_normal_view.empty()) add(OutputTermId::bent_normal, raw.ao.bent_normal_view, true);
  }
  if (computed.ssdo && terms.ssdo) {
    add(OutputTermId::ssdo_direct, raw.ssdo.direct);
    add(OutputTermId::ssdo_direct_denoised, d.direct);
    add(OutputTermId::ssdo_indirect, raw.ssdo.indirect);
    add(OutputTermId::ssdo_indirect_denoised, d.indirect);
  }
  if (terms.ao || terms.ssdo) add(OutputTermId::confidence, raw.confidence);
}

// The composite of the selected terms (kernels/composite.h), over the frame's Env pass as
// background when it has one.
cv::Mat composite_frame(const GBuffer& g, const FrameRequest& request, const TermsComputed& computed,
                        const DenoisedTerms& d) {
  CompositeSettings settings;
  settings.terms = computed.composite_terms;
  // The ambient terms' uniform light is the environment's of the same power, as SSDO's
  // light is the environment itself.
  settings.ambient_radiance = frame_environment(request).mean_radiance();
  const auto env_pass = g.references.find("Env");
  const cv::Mat* background =
      env_pass != g.references.end() && env_pass->second.type() == CV_32FC3 ? &env_pass->second : nullptr;
  auto usable = [](const cv::Mat& m) { return m.empty() ? nullptr : &m; };
  const CompositeInputs in{g.mask,         g.has_albedo() ? &g.albedo : nullptr,
                           usable(d.ao),   usable(d.direct),
                           usable(d.indirect), usable(g.lighting),
                           background,     &frame_environment(request),
                           &g.camera};
  if (const std::string e = validate(in, settings); !e.empty()) throw std::invalid_argument("composite: " + e);
  cv::Mat composite;
  compute_composite(in, settings, composite, {}, request.threads);
  return composite;
}

}  // namespace

namespace {

// Whether the composite reads the frame's lighting (its lighting term).
bool composite_reads_lighting(const FrameRequest& request, const TermsComputed& computed) {
  if (!request.terms.composite) return false;
  return std::any_of(computed.composite_terms.begin(), computed.composite_terms.end(),
                     [](const WeightedTerm& w) { return w.term == CompositeTerm::lighting; });
}

// A finished term that the output stores in half, rounded now to the bits the writer would
// store (half_samples::to_half): half the memory while the later terms are computed.
void keep_in_half(cv::Mat& term, int threads) {
  if (term.empty() || term.depth() == CV_16F) return;
  cv::Mat stored(term.size(), CV_16FC(term.channels()));
  const int samples_per_row = term.cols * term.channels();
  parallel_rows(cv::Range(0, term.rows), threads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      half_samples::to_half(term.ptr<float>(y), samples_per_row, stored.ptr<uint16_t>(y));
  }, 32);
  term = stored;
}

// Releases the inputs no step after the raw terms reads: g's views and its positions, and
// the lighting and albedo unless the composite reads them (the upsampled and denoised terms
// and the composite reuse their memory: the worker's heap keeps freed memory, and fresh
// pages cost a fault each).
void release_read_inputs(GBuffer& g, const FrameRequest& request) {
  g.views.clear();
  g.position_view.release();
  if (!composite_reads_lighting(request, terms_computed(request))) g.lighting.release();
  if (!request.terms.composite) g.albedo.release();
}

// The bent normal, read by nothing but the output (kOutputsInHalf), in half from here when
// it was computed at full resolution (the upsample stores a half grid's in half already).
void keep_bent_normal_in_half(TermOutputs& raw, const FrameRequest& request) {
  keep_in_half(raw.ao.bent_normal_view, request.threads);
}

// The raw terms of g (denoised on their grid as compute_raw_terms), g's inputs released as
// soon as the kernels have read them, before the upsample's outputs are allocated.
TermOutputs raw_terms_releasing(GBuffer& g, const FrameRequest& request, bool denoise_on_grid) {
  TermOutputs raw = compute_raw_terms(g, request, terms_computed(request), denoise_on_grid,
                                      [&] { release_read_inputs(g, request); });
  keep_bent_normal_in_half(raw, request);
  return raw;
}

// finish_frame on the frame's own images (released as they are read no more).
ComputedFrame finish_in_place(GBuffer& g, TermOutputs& raw, std::span<const RawFrame* const> neighbours,
                              const FrameRequest& request) {
  const TermsComputed computed = terms_computed(request);
  ComputedFrame frame;
  // A lone frame's terms on the half grid come upsampled and denoised from compute_terms; a
  // shot's, kept on the grid by compute_raw_frame, are filtered over time on the grid,
  // denoised there and upsampled here, the raw with the denoised.
  if (!raw.grid.empty()) {
    const HalfGridTerms on_grid = filter_grid_over_time(raw.grid, neighbours, request, frame.temporal);
    const cv::Mat no_positions;  // the upsample reads none
    finish_half_grid_terms({g.depth_view, g.normal_view, no_positions, g.mask, g.camera}, raw.grid, on_grid,
                           request.denoise, kOutputsInHalf, raw, request.threads);
    raw.grid = HalfGridTerms();
  }
  DenoisedTerms done = std::move(raw.denoised);
  // The terms on the full grid: filtered over time and denoised at full resolution.
  DenoisedTerms filtered;
  std::vector<TemporalUse> full_grid_uses;
  filter_over_time(g, raw, neighbours, request, computed, filtered, full_grid_uses);
  if (frame.temporal.empty()) frame.temporal = std::move(full_grid_uses);
  std::vector<const cv::Mat*> sources = raw_terms(raw, computed);
  const std::vector<cv::Mat*> slots = term_slots(filtered, computed);
  for (size_t i = 0; i < sources.size(); ++i)
    if (!slots[i]->empty()) sources[i] = slots[i];
  const DenoisedTerms denoised = denoise_terms(g, request, sources, computed, std::move(done));
  // The guides of AO, SSDO, confidence and the denoise are read no more: their memory
  // goes to the composite.
  g.depth_view.release();
  g.normal_view.release();
  g.depth_back_view.release();
  frame.views = std::move(raw.views);
  add_output_terms(request, computed, raw, denoised, frame);
  if (request.terms.composite)
    frame.terms.push_back({output_term_name(OutputTermId::composite), composite_frame(g, request, computed, denoised),
                           SampleType::half, false});
  return frame;
}

}  // namespace

RawFrame compute_raw_frame(GBuffer&& g, const FrameRequest& request) {
  RawFrame f;
  f.raw = raw_terms_releasing(g, request, /*denoise_on_grid=*/false);
  f.gbuffer = std::move(g);
  return f;
}

RawFrame with_raw_terms(GBuffer&& g, TermOutputs raw, const FrameRequest& request) {
  RawFrame f;
  f.raw = std::move(raw);
  release_read_inputs(g, request);
  keep_bent_normal_in_half(f.raw, request);
  f.gbuffer = std::move(g);
  return f;
}

ComputedFrame finish_frame(RawFrame&& f, std::span<const RawFrame* const> neighbours, const FrameRequest& request) {
  return finish_in_place(f.gbuffer, f.raw, neighbours, request);
}

ComputedFrame compute_frame(GBuffer&& g, const FrameRequest& request) {
  TermOutputs raw = raw_terms_releasing(g, request, /*denoise_on_grid=*/true);
  return finish_in_place(g, raw, {}, request);
}

RawFrame temporal_part(const RawFrame& f) {
  // A term on the half grid is read there, with the grid's guides (TermOutputs::grid); one
  // on the full grid at full resolution, with the frame's.
  RawFrame part;
  part.gbuffer.camera = f.gbuffer.camera;
  part.raw.grid = f.raw.grid;
  if (f.raw.grid.ao.empty()) part.raw.ao.ao = f.raw.ao.ao;
  if (f.raw.grid.direct.empty()) {
    part.raw.ssdo.direct = f.raw.ssdo.direct;
    part.raw.ssdo.indirect = f.raw.ssdo.indirect;
  }
  if (!part.raw.ao.ao.empty() || !part.raw.ssdo.direct.empty()) {
    part.gbuffer.depth_view = f.gbuffer.depth_view;
    part.gbuffer.normal_view = f.gbuffer.normal_view;
    part.gbuffer.mask = f.gbuffer.mask;
  }
  return part;
}

ReadOptions reads_for(const FrameRequest& request) {
  ReadOptions read = request.read;
  const TermsComputed c = terms_computed(request);
  const bool composite = request.terms.composite;
  // SSDO's bounce sends albedo x lighting; the composite may add the frame's lighting.
  read.read_lighting = read.read_lighting && (c.ssdo || composite);
  read.read_albedo = read.read_albedo && (c.ssdo || composite || (c.ao && request.ao.multibounce));
  // The one reference a product run uses: the composite's background (a mapped Env pass).
  read.read_references = read.read_references && composite && read.mapping.references.count("Env") > 0;
  return read;
}

ReadOptions view_reads_for(const FrameRequest& request, const ReadOptions& read, bool frame_has_lighting) {
  ReadOptions view = depth_only(read);
  const TermsComputed computed = terms_computed(request);
  const LightReads light =
      light_reads(computed.ao && request.ao.multibounce, computed.ssdo, read.read_lighting && frame_has_lighting);
  // The guard band's light is SSDO's senders'.
  view.read_albedo = read.read_albedo && computed.ssdo && light.albedo;
  view.read_lighting = computed.ssdo && light.lighting;
  return view;
}

const char* output_term_name(OutputTermId term) {
  switch (term) {
    case OutputTermId::ao: return "ao";
    case OutputTermId::ao_denoised: return "ao_denoised";
    case OutputTermId::bent_normal: return "bent_normal";
    case OutputTermId::confidence: return "confidence";
    case OutputTermId::composite: return "composite";
    case OutputTermId::ssdo_direct: return "ssdo_direct";
    case OutputTermId::ssdo_direct_denoised: return "ssdo_direct_denoised";
    case OutputTermId::ssdo_indirect: return "ssdo_indirect";
    case OutputTermId::ssdo_indirect_denoised: return "ssdo_indirect_denoised";
  }
  return "";
}

const std::vector<std::string>& output_term_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> all;
    for (int i = 0; i < kOutputTermCount; ++i) all.emplace_back(output_term_name(OutputTermId(i)));
    return all;
  }();
  return names;
}

void remove_previews_except(const std::string& output, const std::vector<std::string>& kept) {
  std::error_code ec;
  for (const std::string& term : output_term_names())
    if (std::find(kept.begin(), kept.end(), term) == kept.end())
      if (const std::string preview = preview_path(output, term); std::filesystem::is_regular_file(preview, ec))
        std::filesystem::remove(preview, ec);
}

ComputedFrame io_only_frame(const GBuffer& g, const FrameRequest& request) {
  ComputedFrame frame;
  const TermSelection& terms = request.terms;
  const TermsComputed c = terms_computed(request);
  const HalfOutputs& in_half = kOutputsInHalf;  // as compute_frame stores them
  cv::Mat normal_z;
  cv::extractChannel(g.normal_view, normal_z, 2);
  // The stand-ins' sources: a term's stand-in has its source's pixels, in half where
  // compute_frame stores that term in half (one half copy per source, made for the first
  // term that takes it).
  struct StandInSource {
    const cv::Mat& pixels;
    int threads;
    cv::Mat in_half = {};
    cv::Mat stand_in(bool stored_in_half) {
      if (!stored_in_half) return pixels;
      if (in_half.empty()) {
        in_half = pixels;
        keep_in_half(in_half, threads);
      }
      return in_half;
    }
  };
  StandInSource normal_z_source{normal_z, request.threads}, normal_source{g.normal_view, request.threads};
  auto add = [&](OutputTermId term, const cv::Mat& image, bool vector = false) {
    frame.terms.push_back({output_term_name(term), image, SampleType::half, vector});
  };
  if (c.ao && terms.ao) {
    add(OutputTermId::ao, normal_z_source.stand_in(in_half.ao && runs_on_half_grid(request.ao)));
    add(OutputTermId::ao_denoised, normal_z);
    if (has_bent_normal(request.ao))
      add(OutputTermId::bent_normal, normal_source.stand_in(in_half.bent_normal), true);
  }
  if (c.ssdo && terms.ssdo) {
    const cv::Mat raw = normal_source.stand_in(in_half.ssdo && runs_on_half_grid(request.ssdo));
    add(OutputTermId::ssdo_direct, raw);
    add(OutputTermId::ssdo_direct_denoised, g.normal_view);
    add(OutputTermId::ssdo_indirect, raw);
    add(OutputTermId::ssdo_indirect_denoised, g.normal_view);
  }
  if (terms.ao || terms.ssdo) {
    const bool confidence_in_half = in_half.confidence && runs_on_half_grid(confidence_settings(request));
    add(OutputTermId::confidence, normal_z_source.stand_in(confidence_in_half));
  }
  if (terms.composite) add(OutputTermId::composite, g.normal_view);
  return frame;
}

float resolve_radius_world(float radius_given_world, const FrameInfo& info) {
  if (radius_given_world > 0) return radius_given_world;
  if (info.ao_distance_world && *info.ao_distance_world > 0) return *info.ao_distance_world;
  return kDefaultRadiusWorld;
}

bool resolve_frame_radius(FrameRequest& request, const FrameInfo& info, std::string& error) {
  const float radius_world = resolve_radius_world(request.radius_given_world, info);
  request.ao.radius_world = radius_world;
  request.ssdo.radius_world = radius_world;
  std::string e = validate(request.ao);
  if (e.empty()) e = validate(request.ssdo);
  if (!e.empty()) error = info.path + ": the radius " + std::to_string(radius_world) + " (" +
                          (request.radius_given_world > 0 ? "--radius" : "the sidecar's ao_distance") + "): " + e;
  return e.empty();
}

namespace {

// A note for each extra view the kernels did not use, with the reason (kernels/multiview.h).
void note_view_uses(const std::vector<ViewUse>& uses, std::vector<std::string>& notes) {
  for (const ViewUse& u : uses) {
    if (u.used) continue;
    char reason[160];
    if (u.overlap <= 0.0f) std::snprintf(reason, sizeof reason, "it sees none of this frame's surfaces");
    else
      std::snprintf(reason, sizeof reason,
                    "it sees free space in front of %.1f%% of this frame's surfaces it can see (a cut, a moving "
                    "object or a wrong camera)",
                    100.0 * u.contradiction);
    notes.push_back("view " + u.name + " not used: " + reason);
  }
}

}  // namespace

// What the environment light does on this frame that a user may not expect: a frame with
// its own direct-light pass sends that light in the bounce (the light it was rendered
// with), not the environment given; a directional environment needs the camera's world
// orientation, which a camera from --fov does not have.
void note_environment(const FrameRequest& request, const TermsComputed& computed, const GBuffer& g,
                      const FrameInfo& info, std::vector<std::string>& notes) {
  if (!request.environment || !(computed.ssdo || request.terms.composite)) return;
  if (computed.ssdo && !g.lighting.empty()) {
    const auto use =
        std::find_if(info.uses.begin(), info.uses.end(), [](const ChannelUse& u) { return u.input == "lighting"; });
    notes.push_back("ssdo_indirect: its source light is the frame's own direct light" +
                    (use != info.uses.end() ? " (" + use->channels + ")" : std::string()) +
                    ", not the environment given, which lights ssdo_direct and the composite");
  }
  if (request.environment->kind() != EnvironmentKind::constant && info.camera_source.rfind("--fov", 0) == 0)
    notes.push_back("the environment is oriented as if the view were the world (the camera from --fov has no "
                    "world transform): give a camera sidecar or worldToCamera for a directional environment");
}

FrameResult process_frame(const FrameRequest& given, FrameSource* source) {
  FrameResult result;
  result.input_path = given.input_path;
  result.output_path = given.output_path;
  FrameRequest request = given;
  try {
    auto t0 = std::chrono::steady_clock::now();
    const ReadOptions read = reads_for(request);
    ReadResult frame = source ? source->read(request, read) : read_frame(request.input_path, read);
    result.times.read_ms = ms_since(t0);
    result.info = frame.info;
    if (!frame.ok()) {
      result.error = frame.error;
      result.exhausted = frame.exhausted;
      return result;
    }
    if (!resolve_frame_radius(request, frame.info, result.error)) return result;
    const TermsComputed selected = terms_computed(request);
    note_environment(request, selected, frame.gbuffer, frame.info, result.info.notes);
    // Before any compute: a composite that adds the frame's lighting needs a lighting pass.
    if (composite_reads_lighting(request, selected) && frame.gbuffer.lighting.empty()) {
      result.error = request.input_path +
                     ": the composite's term lighting adds the frame's own direct light, and the frame has no "
                     "lighting pass (Cycles' DiffCol x DiffDir, or --map lighting=CHANNEL): leave the term out";
      return result;
    }

    // The G-buffer's images are not written: compute_frame releases each once it is read
    // no more, and their memory goes to the later terms and the writer's buffers (images a
    // term shares stay alive with it).
    Camera camera = frame.gbuffer.camera;
    t0 = std::chrono::steady_clock::now();
    ComputedFrame computed = request.io_only ? io_only_frame(frame.gbuffer, request)
                             : source ? source->compute(request, read, std::move(frame.gbuffer), result.info.notes)
                                      : compute_frame(std::move(frame.gbuffer), request);
    result.times.compute_ms = ms_since(t0);
    note_view_uses(computed.views, result.info.notes);
    if (std::string e = crop_guard_band(computed, camera, request.guard_band_px); !e.empty()) {
      result.error = request.input_path + ": " + e;
      return result;
    }

    if (!request.output_path.empty()) {
      frame.gbuffer = GBuffer();
      t0 = std::chrono::steady_clock::now();
      WriteOptions write = request.write;
      if (write.threads == 0) write.threads = request.threads;  // the frame's thread budget
      // The terms sit where the frame's pixels do (inside its guard band, when cropped).
      const int band = std::max(0, request.guard_band_px);
      write.data_x = result.info.data_x + band;
      write.data_y = result.info.data_y + band;
      if (result.info.display_width_px > 0 && result.info.display_height_px > 0)
        write.display_window = PixelBox{result.info.display_x, result.info.display_y,
                                        result.info.display_x + result.info.display_width_px - 1,
                                        result.info.display_y + result.info.display_height_px - 1};
      const std::string err = write_outputs(request.output_path, computed.terms, camera, write, result.exhausted);
      result.times.write_ms = ms_since(t0);
      if (!err.empty()) {
        result.error = err;
        return result;
      }
      for (const OutputTerm& t : computed.terms) result.terms_written.push_back(t.name);
      remove_previews_except(request.output_path,
                             write.png_previews ? result.terms_written : std::vector<std::string>{});
    }
  } catch (const std::exception& e) {
    result.error = request.input_path + ": " + e.what();
    result.exhausted = resource_failure(e);
  }
  return result;
}

}  // namespace ssdo
