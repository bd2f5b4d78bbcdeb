// Where a neighbouring frame's terms cannot stand for this frame's although the surface is
// the same: the pixels whose surroundings changed between the two frames (the temporal
// filter's per-pixel test, kernels/temporal.h).
//
// AO and SSDO at a point depend on the geometry within their radius R of it, not on the
// point alone: a floor beside a box that moved away keeps its place, normal and depth, and
// its term still changes. The change is seen as free space where the other frame has a
// surface (the free-space contradiction of kernels/multiview.h, per point instead of per
// view): a point of one frame contradicts the other frame when the other frame, at the
// point's projection, sees farther than the point by more than the tolerance, i.e. it sees
// through where this frame has a surface. A point the other frame does not see because
// something is in front of it (a disocclusion of a moving camera, an object that moved
// in front) is no contradiction: it is consistent with a static scene.
//
//   marks_t: points of frame t that neighbour u sees through (what is in t and not in u:
//            the object at its new place), on t's pixels;
//   marks_u: points of u that t sees through (what was in u and is gone from t: the object
//            at its old place), on u's pixels.
//
// Marks are sought on a lattice of every k-th pixel of every k-th row, k = 1 up to 480
// pixels wide and more above (4 at 1920): the search costs that of a frame 480 wide at any
// size, and finds moved objects of 2k pixels or more.
//
// Only marks in a 2x2 block of marks count (an opening by a 2x2 square): a surface about a
// texel wide is sampled by one frame's grid and missed by the other's (a thin pole at the
// half grid, a silhouette's aliasing), which leaves lines of single marks in a still scene,
// while an object that moved by two texels or more leaves regions.
//
// A pixel p of t refuses u's terms when a mark lies within R of its point, in pixels: a
// mark of marks_t within r_t(p) of p, or a mark of marks_u within r_u(p) of p's
// projection into u, where r(p) bounds the pixels the sphere of radius R around p's point
// covers in that camera (changed_radius_px), widened by a pixel and a lattice step. The
// marks' squared distances are exact
// Euclidean distance transforms (Felzenszwalb and Huttenlocher 2012, "Distance Transforms
// of Sampled Functions": the lower envelope of parabolas, row then column), so the test
// costs O(1) per pixel whatever R.
//
// On a plane the surface between the 2x2 texel centres around a projected point is never
// nearer than the smallest of their depths (1 / depth is affine in the pixel), so a static
// scene compares each point with at most its own surface: no mark, except where a surface
// of one frame shows between the texel centres of the other (a silhouette's corner or a
// feature narrower than a pixel), single marks the opening above removes. On the orbit
// shot and the ray caster's truck shot (still scenes, moving cameras) no pixel is left
// changed, on the full and on the half grid.
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "kernels/temporal.h"

namespace ssdo {

// CV_8UC1 at the frame's size: 255 at the foreground pixels of `frame` whose surroundings
// changed in `neighbour` (above), 0 elsewhere; changed_px: how many. Empty when there is
// none (a still scene: nothing allocated). Both frames whole, whatever a caller's roi.
// Deterministic and independent of nthreads.
cv::Mat changed_surroundings(const TemporalFrame& frame, const TemporalFrame& neighbour, const TemporalSettings& s,
                             int64_t& changed_px, int nthreads = 0);

}  // namespace ssdo
