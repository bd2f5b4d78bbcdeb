// Per-pixel confidence of any screen-space estimate (AO or SSDO): how much of the
// neighbourhood the estimator samples was actually observed in the frame. Method-
// independent: it reads only depth, mask, normals and the camera, and the radius the
// estimator uses.
//
// Definition. The neighbourhood of a foreground pixel is the hemisphere H of radius
// radius_world above its tangent plane (the volume AO and SSDO integrate over). Along the
// view ray through a screen tap, H is a segment [a, b] (the ray's chord through the sphere,
// clipped to the positive side of the tangent plane). The frame observes the part of it in
// front of the surface stored at the tap, [a, min(b, t_surface)]; what lies behind that
// surface (behind a large depth gap or a thin occluder), outside the frame, or on a masked
// pixel (background, non-finite input) is unknown. Over taps k spread over the projected
// disk of the sphere,
//
//   confidence = sum_k |observed_k| / sum_k |b_k - a_k|
//
// i.e. the observed fraction of H's volume as sampled along view rays (each chord's length
// is its share of the volume), then averaged with the neighbouring pixels' on the same
// surface (ConfidenceSettings::smoothing_radius_px). 1 = every point of the neighbourhood
// was in front of the stored surfaces: an open plane, a corner seen from outside. 0 = none
// was. 1 on background and where H covers no tap (projected radius below a pixel: the pixel
// itself is all).
//
// With other views of the scene (the neighbouring frames of a shot, kernels/multiview.h),
// observed means observed by any view: the part of a chord this frame does not see (behind
// the stored surface, off-screen, masked) is observed where some view decides it, i.e. sees
// it as free space or has it behind its own surface within the thickness (PointVerdicts).
// Behind a tap's surface the views are asked at view_bins points of the texel's ray, each
// standing for its bin of depth; where the tap reads no surface (off-screen, masked) they
// are asked at one point of the chord, which stands for all of it, and only every 4th
// unknown tap of a pixel asks: their decided fraction stands for all its unknown chords.
#pragma once

#include <span>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/gbuffer.h"
#include "kernels/denoise.h"
#include "kernels/multiview.h"

namespace ssdo {

struct ConfidenceSettings {
  // Radius of the sampled neighbourhood, scene units, (0, inf): the estimator's radius
  // (AoSettings::radius_world or SsdoSettings::radius_world).
  float radius_world = 1.0f;
  // Largest projected radius, pixels of the picture, [2, 4096]: the estimator's own bound
  // (its taps do not reach farther, so neither do these; on the half grid half as many
  // texels, as AoSettings::max_radius_px).
  float max_radius_px = 512.0f;
  // Taps per pixel on the projected disk, [4, 256]. One tap of 16 is ~6% of the fraction;
  // the taps are a Vogel spiral rotated per pixel, so neighbours sample it differently and
  // the smoothing below averages their taps.
  int taps = 16;
  // Half width, in pixels of the grid the confidence runs on, [0, 8], of the depth- and
  // normal-aware blur of the fraction (denoise_bilateral, kernels/denoise.h: sigma 0.75 x
  // the radius, its default depth and normal tolerances, so nothing is averaged across a
  // silhouette or a crease); 0 = none. The fraction varies over the scale of the radius,
  // not of a pixel, and a blur of radius 2 costs 10 reads per pixel where 16 more taps cost
  // 16 chords. Against 256 taps unsmoothed on the shared frames (half grid, upsampled),
  // the mean |difference| over the foreground is 0.007-0.010 with 16 taps and radius 2,
  // 0.011-0.015 with 32 taps unsmoothed, 0.019-0.026 with 16 unsmoothed (docs/performance.md,
  // "The confidence's taps and its smoothing").
  int smoothing_radius_px = 2;
  // Relative depth tolerance of "in front of the stored surface", [0, 0.1]: the same role
  // and default as AoSettings::depth_bias_relative (half-float depth rounds to 4.9e-4 of the
  // value), so that a tap on the pixel's own plane counts as observed.
  float depth_bias_relative = 1e-3f;
  uint32_t seed = 0;  // per-pixel rotation of the tap pattern
  // With views only: bins of planar depth behind each texel's surface, [1, 8], over 2
  // radii (the longest hidden part of a chord); the views are asked once per bin, at its
  // centre, for every foreground texel in one pass in row order
  // (decided_bins_behind_surfaces, kernels/multiview.h), and a tap's hidden part counts the
  // decided bins it overlaps. 2 (bins of a radius); 4 bins separate the orbit's deciles a
  // little more (mean error 0.032 instead of 0.048 at [0.8, 0.9)) for twice the asks.
  int view_bins = 2;
  // 2 (default) = computed on the half-resolution grid and upsampled depth- and
  // normal-aware (compute_terms, kernels/half_resolution.h): the confidence varies over the
  // scale of the radius, not of a pixel, and a quarter of the taps suffice; 1 = every pixel.
  int resolution_divisor = 2;
};

// The confidence runs on the half-resolution grid (resolution_divisor 2).
bool runs_on_half_grid(const ConfidenceSettings& s);

// Empty when valid, else what is wrong (field, value, range).
std::string validate(const ConfidenceSettings& s);

// The blur of the smoothing (ConfidenceSettings::smoothing_radius_px > 0).
DenoiseSettings smoothing(const ConfidenceSettings& s);

// Other views of the scene that the confidence counts as observers.
struct ConfidenceViews {
  std::span<const DepthView> views;  // only the usable ones (measure_view_use: used); empty = none
  MultiViewSettings settings;        // the thickness and depth bias of their verdicts
};

// Writes confidence (CV_32FC1 in [0, 1], allocated at the input size when empty or of the
// wrong size; only roi, empty = all, is written). depth_view CV_32FC1 planar depth (+inf on
// background), normal_view CV_32FC3 unit view-space normals facing the camera, mask CV_8UC1
// (255 = foreground). Deterministic: the same bytes for any thread count. Computed on the
// grid of the inputs (resolution_divisor is compute_terms' to apply). Without views the
// frame's own observation only. frame_origin_px: where the picture's pixel (0, 0) lies in
// these images (AoInputs::frame_origin_px): the taps' rotation is the picture pixel's.
void compute_confidence(const cv::Mat& depth_view, const cv::Mat& normal_view,
                        const cv::Mat& mask, const Camera& camera,
                        const ConfidenceSettings& settings, cv::Mat& confidence,
                        cv::Rect roi = {}, int nthreads = 0, const ConfidenceViews& views = {},
                        cv::Point frame_origin_px = {});

}  // namespace ssdo
