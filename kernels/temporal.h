// Temporal filtering of a frame's raw terms (AO, SSDO light) over the neighbouring frames of
// its shot, past and future: the same surface seen in frames t-K..t+K had its term estimated
// K times more, each with another noise pattern and another half-resolution grid under it.
//
// Backward reprojection (the reverse reprojection cache of Nehab et al. 2007, "Accelerating
// Real-Time Shading with Reverse Reprojection Caching", as TAA's history fetch, with exact
// depth and both cameras instead of motion vectors): each foreground pixel p of frame t is lifted to the world with its
// depth, projected into neighbour u (kernels/reprojection.h) and the neighbour's raw term is
// fetched bilinearly from the 2x2 texels around the projected point, each texel weighted by
//   w = bilinear x max(0, 1 - e / (depth_tolerance_relative x d_p)) x max(0, n_p . n_q)^normal_power
// where e is the texel's distance from p's tangent plane (reprojection.h) and d_p p's depth.
// A texel of another surface (a disocclusion: an occluder in front, a surface that moved, the
// other side of an edge) has e or the normal angle beyond the tolerance and weighs 0; on the
// same surface the weight falls off with the reprojection error. The result is the weighted
// mean of p's own raw value (weight 1) and the neighbours' taps:
//   out(p) = (raw_t(p) + sum w raw_u(q)) / (1 + sum w)
// and exactly raw_t(p) (the same bits) where no tap of any neighbour agrees: there the
// frame's spatial edge-aware denoise (kernels/denoise.h), which the pipeline runs on this
// result, is all the frame gets, as without neighbours.
//
// A neighbour whose surfaces disagree with more than max_disagreement of this frame's
// surface points it sees (a camera cut, a wrong camera, another scene) is not used at all.
//
// The tests above compare the pixel's own surface, but AO and SSDO at a point depend on the
// geometry within their radius of it: the floor beside an object that moved is the same
// surface, and its term (the object's contact shadow) changed. Per pixel and neighbour, the
// filter also looks for a change of the geometry around the point (kernels/temporal_change.h):
// points of one frame that the other sees free space in front of, in either direction (the
// object at its new place, the object at its old place). A pixel with such a point within
// radius_world of its own (in pixels of either camera, a bound) does not take that
// neighbour's taps. An occluded point is no change (a camera's disocclusion), so a static
// scene keeps every neighbour.
//
// Still unseen: a change of the term with no change of the geometry that both frames see (a
// light switched on or moved, an environment that changed), an object that moved where one
// of the frames does not look (off screen, or hidden behind another surface in both), and an
// object or a move narrower than two steps of the lattice the change is sought on (2 pixels
// up to 480 wide, 8 at 1920; kernels/temporal_change.h): there a surface keeps the mean
// over the window.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"

namespace ssdo {

struct TemporalSettings {
  // Tangent-plane tolerance relative to the pixel's depth, (0, 1]: a neighbour's texel
  // farther than this from p's tangent plane weighs 0 (kernels/reprojection.h). 0.01 is 10x
  // the rounding of half-float depth, passes the texels of a surface at any slope (the
  // distance to the plane does not grow with it), and rejects a pole 0.3 in front of a wall
  // seen from 5 units (6%).
  float depth_tolerance_relative = 0.01f;
  // Exponent of the normal weight max(0, n . n_tap)^normal_power, [0, 256]: the denoise's
  // (kernels/denoise.h): half weight at ~17 degrees, creases of 45 degrees and more cut.
  float normal_power = 16.0f;
  // A neighbour is not used when more than this fraction of this frame's foreground points
  // that project into it find another surface there (the plane or normal test above on the
  // nearest texel, or background), [0, 1]. A moving camera disoccludes a few percent per
  // frame; a cut disagrees almost everywhere.
  float max_disagreement = 0.5f;
  // Whether a pixel refuses a neighbour where the geometry within radius_world of its point
  // changed between the two frames (above; kernels/temporal_change.h). false: only the
  // pixel's own surface is compared, and a moving object's contact shadow is averaged over
  // the window.
  bool reject_changed_surroundings = true;
  // The terms' reach, scene units, (0, inf): the largest radius_world of the terms filtered
  // (AoSettings, SsdoSettings; the pipeline passes the frame's). 1 is theirs by default.
  float radius_world = 1.0f;
  // The most pixels of the picture the terms' reach covers, [2, 4096]: the estimators'
  // max_radius_px (their taps go no farther from the pixel), 512 as theirs by default.
  float max_radius_px = 512.0f;
};

// Returns an empty string when valid, else the field, value and range.
std::string validate(const TemporalSettings& s);

// A frame of the shot: its geometry (the kernels' conventions, core/gbuffer.h) and raw terms.
struct TemporalFrame {
  const Camera& camera;
  const cv::Mat& depth_view;   // CV_32FC1 planar, +inf on background
  const cv::Mat& normal_view;  // CV_32FC3 unit view-space normals
  const cv::Mat& mask;         // CV_8UC1, 255 = foreground
  // Raw terms, each CV_32FC1 or CV_32FC3 at the frame's size; a neighbour's in the same
  // order and types as the frame's (at most 16 channels in all).
  std::span<const cv::Mat* const> terms;
};

// What one neighbour contributed.
struct TemporalUse {
  bool used = false;          // false: disagreement above the limit, or no overlap
  float overlap = 0.0f;       // fraction of this frame's foreground points that project into it
  float disagreement = 0.0f;  // fraction of those that find another surface there
  // Foreground pixels of the whole frame (whatever the roi) whose surroundings changed in it
  // (reject_changed_surroundings): they take none of its taps. 0 when not used.
  int64_t changed_px = 0;
};

// Writes dsts[i] (allocated like frame.terms[i]; only roi, empty = all, is written; none may
// share memory with a source): frame.terms[i] filtered over `neighbours` as above. Pixels
// with mask 0 are copied unchanged. With no neighbours, or none used, every dst is a copy of
// its source. Whether a neighbour is used is measured on every 4th pixel of every 4th row
// of the whole frame, whatever the roi. Deterministic and independent of nthreads.
std::vector<TemporalUse> filter_temporal(const TemporalFrame& frame, std::span<const TemporalFrame> neighbours,
                                         const TemporalSettings& settings, std::span<cv::Mat* const> dsts,
                                         cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
