// Half-resolution evaluation of the per-pixel kernels (AO, SSDO, confidence): a kernel runs
// on a grid of half the width and height (a quarter of the pixels), and a depth- and
// normal-aware upsample brings its outputs back to full resolution. The kernels compute on
// whatever grid they are given; compute_terms() below decides which run on the half grid
// (their settings' resolution_divisor), builds the grid once and upsamples their outputs
// together.
//
// Texel (i, j) of the half grid stands for the 2x2 block of pixels (2i.., 2j..) and takes
// the first foreground pixel of the block in the order (0,0), (1,0), (0,1), (1,1): its
// exact depth, normal, view-space position and extra inputs (no averaging, which would
// invent points between a silhouette and the background). The camera keeps its projection
// with the half grid's size, so a kernel projecting radii and points sees the same scene
// at half the pixels.
//
// Upsample (joint bilateral over the 2x2 nearest texels; Kopf et al. 2007, "Joint
// Bilateral Upsampling", SIGGRAPH): bilinear weights x exp(-|dz| / (tol z)) x
// max(0, n . n_texel)^4, tol = kUpsampleDepthRelative; the weighted sum times the inverse
// of the weights' sum. When all four weigh ~0 (a pixel whose surface no nearby texel
// took), the texel of the 4x4 neighbourhood closest in depth is copied; with no foreground
// texel there, the image's fallback value is written.
#pragma once

#include <algorithm>
#include <functional>
#include <span>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "kernels/ao.h"
#include "kernels/confidence.h"
#include "kernels/denoise.h"
#include "kernels/multiview.h"
#include "kernels/ssdo.h"

namespace ssdo {

struct HalfGrid {
  cv::Mat depth_view, normal_view, mask;  // as the full-resolution inputs
  // The source pixels' view-space positions (the full-resolution positions' or, without
  // them, view_positions_from_depth's values); empty when built without positions.
  cv::Mat position_view;
  cv::Mat source;  // CV_32SC2: the full-resolution pixel taken, (-1, -1) if none
  Camera camera;   // the full camera with the half grid's size
};

// The full-resolution views of one frame (CV_32FC1 depth, +inf on background; CV_32FC3
// normal and view positions, positions may be empty for kernels that do not read them;
// CV_8UC1 mask).
struct FullGrid {
  const cv::Mat& depth_view;
  const cv::Mat& normal_view;
  const cv::Mat& position_view;
  const cv::Mat& mask;
  const Camera& camera;
};

// Builds the whole half grid (kernels read taps anywhere on it, whatever the roi).
// with_positions: the texels' positions, copied from full.position_view or, when that is
// empty, computed from the depth at the source pixels only (a full-resolution position
// image is not needed by kernels that run on the grid). Depth, normal and mask do not
// depend on it.
void build_half_grid(const FullGrid& full, HalfGrid& half, int nthreads = 0, bool with_positions = true);

// Each texel's value of a full-resolution image: the value at the pixel the texel took
// (HalfGrid::source), 0 on texels that took none. `full_image` CV_32F of any channel
// count and the full size; `half_image` is allocated at the grid's size.
void sample_at_texels(const HalfGrid& half, const cv::Mat& full_image, cv::Mat& half_image,
                      int nthreads = 0);

// exp(x), x <= 0, as the upsample weights evaluate their depth term exp(-|dz| / (tol z)):
// libmvec's vector expf where the kernels are built with AVX2 (within 3 ulp of std::exp),
// else std::exp.
float upsample_depth_falloff(float x);

// The texels the upsample of the full-resolution roi reads.
cv::Rect half_grid_roi(const cv::Rect& full_roi, const cv::Size& full_size);

// What the upsample does to an image's upsampled values, row by row while they are in
// cache (a separate pass would read and write the whole image again):
// - none: the values as blended;
// - clamp_unit_interval: each value clamped to [0, 1] (a weighted mean of values in [0, 1]
//   is, up to rounding);
// - unit_vector: 3 channels; each foreground pixel's vector times the inverse of its length
//   sqrt((x^2 + y^2) + z^2) in float (a weighted mean of unit vectors is shorter), or, at
//   zero length (<= 1e-12), the pixel's normal
//   (FullGrid::normal_view); background pixels keep `background`.
enum class UpsampleFinish { none, clamp_unit_interval, unit_vector };

// One image to bring to full resolution: `half` (CV_32F, any channels, the half grid's
// size) into `full` (the same channels, the full size, allocated by the caller): CV_32F, or
// CV_16F to store the values in half (core/half_samples.h: round to nearest even, the bits
// a half-float output stores) at half the memory. Background pixels get `background`,
// pixels with no foreground texel near get `fallback`; then `finish`, on the floats.
struct UpsampleImage {
  const cv::Mat& half;
  cv::Mat& full;
  cv::Scalar background;
  cv::Scalar fallback;
  UpsampleFinish finish = UpsampleFinish::none;
};

// Writes the pixels of `roi` of every image. The texel weights depend on the guides only:
// they are computed once per pixel for all the images.
void upsample_from_half_grid(const FullGrid& full, const HalfGrid& half,
                             std::span<const UpsampleImage> images, const cv::Rect& roi,
                             int nthreads = 0);

// ---- The terms of a frame, each at the resolution its settings ask ----
// The pipeline (service/pipeline.cpp) computes a frame's AO, SSDO and confidence with
// compute_terms; the tests, accuracy suites and benchmarks of one kernel call the same
// function through the compute_*_at_resolution wrappers, so every caller gets the bytes a
// frame gets. It lives here, beside the grid it builds, rather than in service/: the
// kernels' tests link the kernels only.

// The frame's full-resolution inputs (as AoInputs and SsdoInputs).
struct TermInputs {
  const cv::Mat& depth_view;   // CV_32FC1 planar depth (+inf on background)
  const cv::Mat& normal_view;  // CV_32FC3 unit view-space normals
  // CV_32FC3 view-space positions, or empty: then computed here (view_positions_from_depth)
  // when AO or SSDO runs at full resolution (the half grid computes its texels' own).
  const cv::Mat& position_view;
  const cv::Mat& mask;  // CV_8UC1, 255 = foreground
  const Camera& camera;
  const Environment* environment = nullptr;      // SSDO's light; required with SSDO
  const cv::Mat* albedo = nullptr;               // CV_32FC3 or null
  const cv::Mat* lighting = nullptr;             // CV_32FC3 or null (SSDO's senders)
  // CV_32FC1 second depth layer or null (GBuffer::depth_back_view): the occluder thickness of
  // AO and SSDO, sampled at the texels on the half grid.
  const cv::Mat* depth_back_view = nullptr;
  // Other views of the scene (GBuffer::views): the occluders of AO and SSDO get the occupied
  // interval all views agree on (occupancy_from_views, kernels/multiview.h), computed once
  // on each grid a kernel runs on, in place of depth_back_view; the confidence counts what
  // the used views observe (ConfidenceViews, kernels/confidence.h).
  std::span<const DepthView> views = {};
  // GBuffer::data_origin_px: the per-pixel noise is keyed to the picture's pixels (on the
  // half grid, to its texels: a crop at an even offset gets the whole frame's).
  cv::Point data_origin_px{0, 0};
};

// Which of the terms upsampled from the half grid compute_terms stores in half.
struct HalfOutputs {
  bool bent_normal = false;
  bool ssdo = false;  // the raw SSDO terms
  bool ao = false;    // the raw AO
  bool confidence = false;
};

// The terms to compute, each with its settings; null = not computed.
struct TermSettings {
  const AoSettings* ao = nullptr;
  const SsdoSettings* ssdo = nullptr;
  const ConfidenceSettings* confidence = nullptr;
  // The edge-aware denoise (kernels/denoise.h) of the AO and SSDO terms that run on the half
  // grid, run on that grid before the upsample, its radius, spacing and sigma counted in
  // texels; null = not denoised here. It reads a quarter of the pixels that the same
  // footprint at full resolution (scaled_to_grid) reads, and its taps are the grid's
  // estimates themselves instead of their blends. Terms on the full grid are not denoised
  // here.
  const DenoiseSettings* denoise = nullptr;
  // Upsampled outputs stored in half (UpsampleImage: CV_16F, the bits a half-float output
  // would store), at half the memory: for those that nothing but such an output reads.
  HalfOutputs stored_in_half = {};
  // Keep the raw AO and SSDO terms computed on the half grid there, with the grid
  // (TermOutputs::grid), instead of upsampling them: for a step on the grid before they are
  // denoised (a shot's filter over time, kernels/temporal.h); finish_half_grid_terms then
  // denoises and upsamples them. (The bent normal and the confidence are upsampled as usual.)
  // For the whole frame only (an empty roi).
  bool keep_grid_terms = false;
};

// A radius bound in pixels of the picture (the settings' max_radius_px) in texels of a grid
// at 1 / resolution_divisor of its resolution, as compute_terms gives it to the kernels on
// that grid (and the pipeline to the temporal filter there): divided, and at least 2, the
// bound's least valid value.
inline float max_radius_on_grid(float max_radius_px, int resolution_divisor) {
  return std::max(2.0f, max_radius_px / float(resolution_divisor));
}

// The multi-view occupancy settings of the selected terms: AO's thickness, radius and depth
// bias (else SSDO's, else the confidence's radius), decided as far as twice the radius
// behind each surface.
MultiViewSettings multiview_settings(const TermSettings& settings);

// The denoised AO and SSDO terms (TermSettings::denoise), at full resolution like the raw.
struct DenoisedTerms {
  cv::Mat ao;                // CV_32FC1, clamped to [0, 1] as the raw AO
  cv::Mat direct, indirect;  // CV_32FC3
};

// The raw AO and SSDO terms computed on the half grid, and the grid (its guides and camera;
// no positions or sources): what a step on the grid after compute_terms reads.
struct HalfGridTerms {
  HalfGrid grid;
  cv::Mat ao;                // CV_32FC1 AO on the grid, or empty (AO not on the grid)
  cv::Mat direct, indirect;  // CV_32FC3 SSDO light on the grid, or empty

  bool empty() const { return ao.empty() && direct.empty(); }
};

struct TermOutputs {
  AoOutput ao;
  SsdoOutput ssdo;
  // CV_32FC1 (compute_confidence); CV_16FC1 when upsampled with stored_in_half.confidence.
  // Likewise in half when upsampled with stored_in_half: the raw AO (.ao), the raw SSDO
  // terms (.ssdo) and the bent normal (.bent_normal).
  cv::Mat confidence;
  // With TermSettings::denoise, the denoised terms of AO and SSDO when they run on the half
  // grid; empty otherwise.
  DenoisedTerms denoised;
  // With TermSettings::keep_grid_terms, the raw AO and SSDO terms that ran on the half grid,
  // on the grid (their full-resolution images above are then left empty); empty otherwise.
  HalfGridTerms grid;
  std::vector<ViewUse> views;  // what each of TermInputs::views contributed
};

// What the terms read of a frame's light (and of its views' guard band): the albedo for
// AO's multi-bounce, and for SSDO's senders when the frame has no lighting of its own; the
// lighting for SSDO's senders when it has.
struct LightReads {
  bool albedo = false, lighting = false;
};
LightReads light_reads(bool ao_multibounce, bool ssdo, bool frame_has_lighting);

// Computes the selected terms for the pixels of roi (empty = all), each on the full grid or
// on the frame's one half grid (runs_on_half_grid of its settings): the half grid is built
// once (with positions when AO or SSDO runs on it), each half-resolution kernel runs on
// the texels of the roi (AO with the albedo at the texels for multi-bounce only; SSDO with
// the lighting at the texels when given, else the albedo), and their outputs are upsampled
// in one pass (background and fallback: AO 1, bent normal 0, SSDO 0, confidence 1), which
// also clamps AO to [0, 1] and renormalises the bent normals (UpsampleFinish). Outputs as
// each kernel's.
// inputs_read, when given, is called once every kernel has run, before the upsample's
// full-resolution outputs are allocated: the caller may free there what no later step of
// its own reads, and the outputs reuse that memory. After it returns, only in.depth_view,
// in.normal_view and in.mask are read (by the upsample).
void compute_terms(const TermInputs& in, const TermSettings& settings, TermOutputs& out, cv::Rect roi = {},
                   int nthreads = 0, const std::function<void()>& inputs_read = {});

// The rest of compute_terms for the terms it kept on the half grid (TermSettings::
// keep_grid_terms): `to_denoise` (the raw terms themselves, or other values on the same grid,
// such as a shot's terms filtered over time) denoised on the grid with its guides
// (kernels/denoise.h, `settings` counted in texels), then the raw terms and the denoised
// ones upsampled in one pass: out.ao.ao, out.ssdo.direct and indirect (stored_in_half.ssdo:
// CV_16F), out.denoised's, for the terms present in `raw`; the others are left as they are.
// With to_denoise = raw, the bits compute_terms gives with TermSettings::denoise.
void finish_half_grid_terms(const FullGrid& full, const HalfGridTerms& raw, const HalfGridTerms& to_denoise,
                            const DenoiseSettings& settings, const HalfOutputs& stored_in_half, TermOutputs& out,
                            int nthreads = 0);

// One term through compute_terms: what a frame computes for it.
void compute_ao_at_resolution(const AoInputs& in, const AoSettings& settings, AoOutput& out, cv::Rect roi = {},
                              int nthreads = 0);
void compute_ssdo_at_resolution(const SsdoInputs& in, const SsdoSettings& settings, SsdoOutput& out,
                                cv::Rect roi = {}, int nthreads = 0);
void compute_confidence_at_resolution(const cv::Mat& depth_view, const cv::Mat& normal_view, const cv::Mat& mask,
                                      const Camera& camera, const ConfidenceSettings& settings,
                                      cv::Mat& confidence, cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
