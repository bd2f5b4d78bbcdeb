// Other views of the scene (the neighbouring frames of a shot) as knowledge of what this
// frame hides: the occupied depth interval behind each visible surface.
//
// One depth buffer cannot tell a thin pole from a wall: behind every visible surface the
// estimators assume thickness_world of solid, then free space. Other cameras of the same
// scene observe some of that space. The rule (the SSDO paper's remedy for hidden geometry,
// Ritschel et al. 2009, sec. 3.3, with additional cameras in place of extra renders):
//
//   a point q is occupied  <=>  no view sees free space at q, and some view has q behind
//                               its visible surface within the thickness
//
// where a view sees free space at q when q projects inside its image in front of the
// surface it stores there. This frame is one of the views (its own interval is
// [front, front + thickness], or [front, back] with a back layer from the file).
//
// Walking each pixel's view ray from its visible surface backwards, the first point that
// is not occupied ends the pixel's occluder: that depth is the pixel's back layer, which the
// estimators that model thickness already take (AoInputs::depth_back_view: GTAO's
// visibility mask, the raymarch oracle). Occupancy is only ever changed behind this frame's
// visible surfaces, never in front of them (what this frame sees to be free stays free), so
// a view that disagrees (a moving object) can at worst change a surface's thickness.
//
// Conservative free-space test: a view's depth is a sample at each pixel centre, and a point
// on a surface seen at a grazing angle may lie in front of the sample nearest to it. The
// test compares with the smallest depth of the 2x2 pixel centres around the projected
// point (on a plane, the surface between those centres is never nearer than the smallest
// of them), less a relative bias for the depth's rounding.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/gbuffer.h"

namespace ssdo {

struct MultiViewSettings {
  // Assumed thickness behind every visible surface of this frame, scene units, (0, inf):
  // the estimators' (effective_thickness_world of the AO settings).
  float thickness_world = 0.5f;
  // How far behind each visible surface occupancy is decided, scene units, (0, inf). Past
  // it the occluder counts as solid (back = +inf) if still occupied. Twice the AO radius
  // covers every point of a tap's segment that lies within the radius of a pixel at most a
  // radius away.
  float reach_world = 2.0f;
  // Depth bias of the free-space test relative to the view's depth, [0, 0.1]: a view sees
  // q free only when q is nearer than its surface by more than this fraction (the
  // estimators' depth_bias_relative; 1e-3 covers half-float depth twice).
  float depth_bias_relative = 1e-3f;
  // Points sampled along [front, front + reach_world], [2, 64], then `refinements`
  // bisection steps, [0, 16], on the first change from occupied to free. 8 samples and 2
  // steps place the occluder's end within reach_world / 32 (a sixteenth of the radius): the
  // synthetic shot's and the orbit's error with views are those of 12 and 4 within 2%, for
  // 40% fewer steps of the walk that costs a view pass its most.
  int samples = 8;
  int refinements = 2;
  // A view is not used when it sees free space in front of more than this fraction of the
  // surface points of this frame it can see, [0, 1]: a cut, a wrong camera or a different
  // scene. Consistent views of a static scene contradict no point.
  float max_contradiction = 0.05f;
};

std::string validate(const MultiViewSettings& s);

// What one view contributed.
struct ViewUse {
  std::string name;           // DepthView::name
  bool used = false;          // false: rejected (contradiction above the limit, or no overlap)
  float overlap = 0.0f;       // fraction of this frame's foreground surface points in the view
  float contradiction = 0.0f; // fraction of those it sees free space in front of
};

// The frame's own inputs.
struct MultiViewInputs {
  const cv::Mat& depth_view;  // CV_32FC1 planar depth, +inf on background
  const cv::Mat& mask;        // CV_8UC1, 255 = foreground
  const Camera& camera;
  // CV_32FC1 back layer from the file (GBuffer::depth_back_view) or null: this frame's own
  // interval is [front, back] instead of [front, front + thickness].
  const cv::Mat* depth_back_view = nullptr;
};

// Writes `depth_back_view` (CV_32FC1 at the frame's size): for each foreground pixel the
// planar depth where its occluder ends by the rule above (+inf: solid as far as
// reach_world), +inf on background. Leaves it empty, and returns every view as unused,
// when no view is usable: the frame is then computed exactly as alone. Deterministic and
// independent of nthreads.
std::vector<ViewUse> occupancy_from_views(const MultiViewInputs& in, std::span<const DepthView> views,
                                          const MultiViewSettings& s, cv::Mat& depth_back_view,
                                          int nthreads = 0);

// The views as dense as a grid `grid_width_px` texels wide: a view wider than the grid by a
// factor f >= 2 (rounded) becomes one texel per f x f block of its pixels holding the
// block's nearest depth, with its camera's grid scaled alike (the projection unchanged, as
// the half grid's camera; kernels/half_resolution.h). The nearest depth keeps the
// free-space test conservative: a point in front of a texel is in front of every pixel of
// its block. A grid reads each texel's verdict where the view's full resolution would cost
// f^2 times its memory in scattered reads for detail the grid cannot resolve. Views at most
// as dense as the grid are copied as they are (a cv::Mat header, not the pixels).
std::vector<DepthView> views_at_density(std::span<const DepthView> views, int grid_width_px, int nthreads = 0);

// ---- Off-screen taps: the grid extended past the screen's edges ----
// A tap that leaves the picture finds nothing in one frame, so an occluder just outside the
// frame is missed. A neighbouring view that saw past the edge knows what is there: its
// surfaces, forward-projected into this camera, fill a guard band of texels around the
// grid, where the estimators' taps find them as occluders. The estimators shade only the
// inside (their roi) and take the band's texels as they take any other: depth, position,
// and the assumed thickness behind.

// The band's width in texels: how far past an edge the taps of the grid's pixels reach,
// max over foreground pixels p within reach of an edge of (projected radius at p - p's
// distance to that edge), the projected radius min(max_radius_px, radius_world x pixels per
// unit at p's depth); rounded up to a multiple of 4 and at most a quarter of the grid's
// larger side (past that the band would cost more than the frame). 0 when no tap leaves.
int guard_band_texels(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera, float radius_world,
                      float max_radius_px, int nthreads = 0);

// Texels added on each side of a grid.
struct BandMargins {
  int left = 0, top = 0, right = 0, bottom = 0;
  bool any() const { return left > 0 || top > 0 || right > 0 || bottom > 0; }
  bool operator==(const BandMargins&) const = default;
};

// `camera` with `m` more pixels on each side and the same ray through every pixel of the
// original grid: pixel (x, y) of the original is (x + m.left, y + m.top) of this one. With
// W' = W + left + right and H' = H + top + bottom, its projection is the original's with
// NDC x scaled by W / W' and moved by (left - right) / W', NDC y scaled by H / H' and moved
// by (bottom - top) / H' (no move with equal sides).
Camera widened_camera(const Camera& camera, const BandMargins& m);
inline Camera widened_camera(const Camera& camera, int margin_px) {
  return widened_camera(camera, BandMargins{margin_px, margin_px, margin_px, margin_px});
}

// A grid extended by a guard band: `depth_view`, `mask` and `depth_back_view` at the widened
// camera's size, the original grid inside (at (margins.left, margins.top)), and in the band
// the nearest surface the views saw there (planar depth in this camera; +inf and mask 0
// where no view saw any), with the occupancy of the views behind it (the rule above; a band
// texel's own interval is the assumed thickness). `albedo` and `lighting` (CV_32FC3 at the
// same size, or empty when no used view has them): in the band, those of the view pixel
// whose surface the texel holds (0 where it holds none or its view has none); 0 inside.
struct GuardBand {
  BandMargins margins;
  Camera camera;
  cv::Mat depth_view, mask, depth_back_view;
  cv::Mat albedo, lighting;
  cv::Rect inside() const;  // the original grid in the extended images
};

// Fills `band` from the grid (in, with the occupancy's back layer `depth_back_view`, or
// empty for front + thickness) and the views marked used in `uses` (occupancy_from_views):
// every view pixel of `stride_px` x `stride_px` (a view denser than the grid needs a
// sample per texel, not per pixel) is lifted to the world and projected into the widened
// camera; where it lands in the band, the nearest depth wins (a minimum over depth, then
// over the views' order and the pixel's: the same result for any thread count), with its
// albedo and lighting when its view has them; each side of the band is then narrowed to the farthest
// surface it got there (band.margins each <= margin_px; 0 on a side where the views saw
// nothing past the edge, all 0: the frame as it is). Deterministic.
void extend_with_views(const MultiViewInputs& in, const cv::Mat& depth_back_view,
                       std::span<const DepthView> views, std::span<const ViewUse> uses,
                       const MultiViewSettings& s, int margin_px, GuardBand& band, int nthreads = 0);

}  // namespace ssdo

namespace ssdo {

// The views' usefulness alone (the `used`, `overlap` and `contradiction` occupancy_from_views
// reports, measured the same way), for a kernel that asks the views about points without
// needing the back layer.
std::vector<ViewUse> measure_view_use(const MultiViewInputs& in, std::span<const DepthView> views,
                                      const MultiViewSettings& s, int nthreads = 0);

// Which of `bins` depth bins behind each texel's surface the views decide (by the rule above,
// as PointVerdicts::decided): bit i of a texel is set when the point at planar depth
// d x surface_scale + (i + 0.5) x bin_depth on the ray through the texel's centre (d its
// depth) is decided; 0 on masked texels. CV_8UC1 at the frame's size, bins in [1, 8]. Pass
// only the views to trust. One pass in the frame's row order: neighbouring texels read
// neighbouring pixels of each view.
cv::Mat decided_bins_behind_surfaces(const MultiViewInputs& in, std::span<const DepthView> views,
                                     const MultiViewSettings& s, float surface_scale, float bin_depth, int bins,
                                     int nthreads = 0);

// The views' verdicts on single points of a frame's view space, by the rule above: a point
// is decided when some view sees it as free space, or has it behind its visible surface
// within thickness_world (the free-space test as occupancy_from_views', the same bias).
// What the confidence (kernels/confidence.h) counts as observed behind this frame's
// surfaces. Pass only the views to trust (those measure_view_use reports used).
class PointVerdicts {
 public:
  PointVerdicts(const Camera& frame_camera, std::span<const DepthView> views, const MultiViewSettings& s);
  ~PointVerdicts();
  PointVerdicts(const PointVerdicts&) = delete;
  PointVerdicts& operator=(const PointVerdicts&) = delete;

  bool empty() const;  // no view: nothing is decided
  // point_view: a point of the frame's view space.
  bool decided(const glm::vec3& point_view) const;
  // The same for many points at once (several per instruction): decided[i] is 1 when
  // points_view[i] is decided, else 0. decided.size() == points_view.size().
  void decided(std::span<const glm::vec3> points_view, std::span<uint8_t> decided) const;

 private:
  struct Impl;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace ssdo
