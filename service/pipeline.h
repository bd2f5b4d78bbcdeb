// One frame's way through the product: read (formats) -> compute (kernels) -> write
// (formats). A request is a value; `process`, `eval` and `serve` all build one.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "formats/gbuffer_reader.h"
#include "formats/output_writer.h"
#include "kernels/ao.h"
#include "kernels/composite.h"
#include "kernels/denoise.h"
#include "kernels/environment.h"
#include "kernels/half_resolution.h"
#include "kernels/multiview.h"
#include "core/gbuffer.h"
#include "kernels/ssdo.h"
#include "kernels/temporal.h"
#include "service/quality.h"
#include "service/sequence.h"

namespace ssdo {

// Which terms a request computes. Names as on the command line (--terms):
//   ao          AO, its denoised version and the bent normal (when the method has one)
//   ssdo        SSDO direct and indirect light, raw and denoised
//   composite   the composited image of the selected terms
struct TermSelection {
  bool ao = true;
  bool ssdo = false;
  bool composite = true;
};

// Parses "ao,ssdo,composite" (also "all"); on error returns false and says why.
bool parse_terms(const std::string& list, TermSelection& terms, std::string& error);
std::string to_string(const TermSelection& terms);

struct FrameRequest {
  std::string input_path;
  // The name the request gave for the input when input_path is an opened descriptor's
  // ("/proc/self/fd/N", service/job_files.h): the frame's identity in its sequence. Empty =
  // input_path.
  std::string input_name;
  std::string output_path;    // the EXR to write; empty = compute only (eval)
  ReadOptions read;
  TermSelection terms;
  AoSettings ao;
  // --quality auto's choice of ao's method and preset; nullopt = --method and --preset.
  std::optional<QualityChoice> quality;
  SsdoSettings ssdo;
  DenoiseSettings denoise;
  // The environment light of the SSDO terms and the composite's background (world space,
  // built once per batch and shared by its frames). Null = constant radiance 1.
  std::shared_ptr<const Environment> environment;
  // Composite terms; empty = the default for the selected terms: SSDO direct + indirect
  // when SSDO is computed (Cycles' DiffCol x (DiffDir + DiffInd)), else albedo x AO.
  std::vector<WeightedTerm> composite_terms;
  WriteOptions write;
  // Threads of the kernels: 1 = serial, N > 1 = at most N of the process's pool, 0 = the
  // whole pool (sized once per process: apply_thread_budget, service/parallelism.h).
  int threads = 0;
  // I/O floor (benchmarks): read what the terms need and write the same channels (names,
  // types, size) with the frame's own normals standing in for every term, computing
  // nothing. process_frame's read and write times are then those of a full run.
  bool io_only = false;
  // Frames rendered with overscan: pixels cropped off each side of every term after
  // computing on the whole frame, before writing (crop_guard_band, service/guard_band.h).
  int guard_band_px = 0;
  // --radius as given; 0 = not given: the frame's own AO distance, else 1
  // (resolve_radius_world). ao.radius_world and ssdo.radius_world hold it when given.
  float radius_given_world = 0;
  // Extra views (GBuffer::views): up to views_per_side of `neighbours` on each side of the
  // frame, chosen by parallax (service/view_selection.h) and read by the worker's sequence
  // context (service/sequence_context.h). 0 = the frame alone.
  int views_per_side = 0;
  std::vector<NeighbourFrame> neighbours;
  // Temporal filtering (kernels/temporal.h): the denoised terms of the frame are the denoise
  // of its raw terms filtered over the raw terms of the frames up to temporal_per_side
  // places before and after it among `neighbours` (computed once per batch: the worker's
  // sequence context). The raw terms are written unfiltered. 0 = the frame alone.
  int temporal_per_side = 0;
  TemporalSettings temporal;
};

// The AO distance a frame gets when neither --radius nor the frame gives one.
inline constexpr float kDefaultRadiusWorld = 1.0f;

// The AO and SSDO radius of a frame, the same in every command (process, serve, eval,
// bench): --radius when given (> 0), else the frame's own AO distance (its sidecar's
// "ao_distance": the radius its renderer's AO pass used), else kDefaultRadiusWorld.
float resolve_radius_world(float radius_given_world, const FrameInfo& info);

// `request` with ao.radius_world and ssdo.radius_world resolved for the frame. False with
// a message naming the frame when the frame's AO distance is unusable for the settings
// (e.g. larger than max_radius_px allows).
bool resolve_frame_radius(FrameRequest& request, const FrameInfo& info, std::string& error);

struct StageTimes {
  double read_ms = 0, compute_ms = 0, write_ms = 0;
};

struct FrameResult {
  std::string input_path, output_path;
  std::string error;          // empty on success
  // A failure that was memory or a thread running out (core/resource_failure.h): reading,
  // computing or writing the frame again with less, or in a new process, may succeed.
  ResourceFailure exhausted = ResourceFailure::none;
  StageTimes times;
  FrameInfo info;
  std::vector<std::string> terms_written;
  bool ok() const { return error.empty(); }
};

// The computed images of a frame, by output name, in the order they are written.
struct ComputedFrame {
  std::vector<OutputTerm> terms;
  std::vector<ViewUse> views;  // what each of the G-buffer's extra views contributed
  std::vector<TemporalUse> temporal;  // what each temporal neighbour contributed (finish_frame)
  const cv::Mat* find(const std::string& name) const;
};

// A frame halfway through compute_frame: its raw terms (AO, SSDO, confidence) and the G-buffer
// they were computed on (without its extra views and positions, which no later step reads).
// What a neighbouring frame lends the temporal filter (temporal_part).
struct RawFrame {
  GBuffer gbuffer;
  TermOutputs raw;
};

// A frame in two steps, for temporal filtering: the raw terms (those computed on the half
// grid kept there, with the grid, not yet upsampled: TermOutputs::grid), then the rest: each
// term filtered over the same term of `neighbours` when given (kernels/temporal.h) on the
// grid it was computed on, denoised there (a half grid's raw and denoised terms then
// upsampled in one pass: finish_half_grid_terms), composited. finish_frame releases the
// frame's images as compute_frame does. finish_frame(compute_raw_frame(g, r), {}, r) gives
// the bits of compute_frame(g, r), which denoises a lone frame's half-grid terms inside
// compute_terms and upsamples them with the raw ones in one pass.
RawFrame compute_raw_frame(GBuffer&& gbuffer, const FrameRequest& request);
ComputedFrame finish_frame(RawFrame&& frame, std::span<const RawFrame* const> neighbours, const FrameRequest& request);
// The raw frame of a G-buffer whose raw terms `raw` were computed before, by
// compute_raw_frame of the same frame and request: the G-buffer released as it releases it.
RawFrame with_raw_terms(GBuffer&& gbuffer, TermOutputs raw, const FrameRequest& request);

// What of a frame's raw frame the temporal filter reads when it is a neighbour: the camera,
// the half grid with its raw terms, and for terms on the full grid their raw images with
// the frame's depth, normals and mask (image headers: no copy).
RawFrame temporal_part(const RawFrame& frame);

// Computes the selected terms for a frame already in memory (no I/O).
ComputedFrame compute_frame(const GBuffer& gbuffer, const FrameRequest& request);
// The same, releasing each of the G-buffer's images once no later step reads it (positions
// before the denoise, depth and normals before the composite): a frame's peak memory is
// lower.
ComputedFrame compute_frame(GBuffer&& gbuffer, const FrameRequest& request);

// Every term compute_frame may return. Its name (output_term_name) is the output's
// channel (layer) and the preview's, NAME.ssdo.<term>.png.
enum class OutputTermId {
  ao,
  ao_denoised,
  bent_normal,
  confidence,
  composite,
  ssdo_direct,
  ssdo_direct_denoised,
  ssdo_indirect,
  ssdo_indirect_denoised,
};
inline constexpr int kOutputTermCount = int(OutputTermId::ssdo_indirect_denoised) + 1;
const char* output_term_name(OutputTermId term);

// The name of every term compute_frame may return, in OutputTermId's order.
const std::vector<std::string>& output_term_names();

// Removes the previews of `output` (OUT/NAME.ssdo.<term>.png, formats/output_writer.h) of
// every term but `kept`: after an output written without previews, or with those of other
// terms, the pictures of an earlier version of it would pass for its own.
void remove_previews_except(const std::string& output, const std::vector<std::string>& kept);

// The terms compute_frame would return (names, channels, sample types, same order) with
// stand-in images: the frame's view-space normals (their z for one-channel terms). For
// FrameRequest::io_only.
ComputedFrame io_only_frame(const GBuffer& gbuffer, const FrameRequest& request);

// The request's read options narrowed to the inputs its terms use: lighting only for SSDO,
// albedo for SSDO, the composite or multi-bounce AO, references only for a composite
// whose background is a mapped Env pass. Channels not read are neither converted nor held
// (OpenEXR still inflates whole chunks: every channel of a ZIP block is in one stream).
ReadOptions reads_for(const FrameRequest& request);

// What the request's neighbouring frames are read for as views: their depth, and where the
// request computes SSDO, as far as `read` reads them, the light of the senders they show
// past this frame's edges (kernels/multiview.h, the guard band) as the kernels read it on
// the frame (light_reads, kernels/half_resolution.h): the lighting when the frame has its
// own, else the albedo; the albedo also for multi-bounce AO. What the kernels would not
// read is neither read nor kept (at 1080p, 24 MiB per view and channel).
ReadOptions view_reads_for(const FrameRequest& request, const ReadOptions& read, bool frame_has_lighting);

// Where process_frame gets its frame: read and completed (service/frame_inputs.h), with
// its extra views attached (GBuffer::views). Without one: read_frame, no views.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // `read`: the request's read options narrowed to its terms (reads_for).
  virtual ReadResult read(const FrameRequest& request, const ReadOptions& read) = 0;
  // The frame's terms from the G-buffer read() returned. With temporal filtering
  // (FrameRequest::temporal_per_side > 0) a source that knows the frame's sequence filters
  // over its neighbours' raw terms, each computed once (service/sequence_context.h), and
  // adds a note for each neighbour it could not use; this one computes the frame alone.
  virtual ComputedFrame compute(const FrameRequest& request, const ReadOptions& read, GBuffer&& frame,
                                std::vector<std::string>& notes) {
    (void)read, (void)notes;
    return compute_frame(std::move(frame), request);
  }
};

// Milliseconds of the steady clock since t0: every stage's timing.
double ms_since(std::chrono::steady_clock::time_point t0);

// Reads, computes and writes one frame. Never throws: failures are in result.error.
FrameResult process_frame(const FrameRequest& request, FrameSource* source = nullptr);

}  // namespace ssdo
