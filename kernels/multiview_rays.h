// What the multi-view passes share (kernels/multiview.cpp, and its per-pixel passes in
// kernels/multiview_lanes.cpp): each view as seen from this frame, and the per-pixel passes
// (the rule and the free-space test in kernels/multiview.h). Internal to the kernels.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/gbuffer.h"
#include "kernels/multiview.h"

namespace ssdo::multiview_detail {

inline constexpr float kInfinity = std::numeric_limits<float>::infinity();

// A view as seen from this frame: this frame's view space straight to the view's clip
// space and planar depth (both affine, so along a pixel's ray they are linear in depth).
struct ViewGeometry {
  glm::mat4 clip_from_frame_view;  // view_to_clip_v * world_to_view_v * view_to_world
  glm::vec4 depth_from_frame_view; // planar depth in the view: -(row z of the rigid part)
  const cv::Mat* depth_view;
  float width_px, height_px;
};

inline ViewGeometry view_geometry(const Camera& frame, const DepthView& v) {
  const glm::mat4 rigid = v.camera.world_to_view * frame.view_to_world;
  // glm is column-major: the z row is (m[0][2], m[1][2], m[2][2], m[3][2]).
  const glm::vec4 depth_row(-rigid[0][2], -rigid[1][2], -rigid[2][2], -rigid[3][2]);
  return {v.camera.view_to_clip * rigid, depth_row, &v.depth_view, float(v.camera.width_px),
          float(v.camera.height_px)};
}

struct Constants {
  MultiViewSettings s;
  std::vector<ViewGeometry> views;
};

// The views (those marked used, when `uses` is given) as seen from `frame`.
inline Constants views_from(const Camera& frame, std::span<const DepthView> views, const MultiViewSettings& s,
                            std::span<const ViewUse> uses = {}) {
  Constants k{s, {}};
  for (size_t i = 0; i < views.size(); ++i)
    if (uses.empty() || uses[i].used) k.views.push_back(view_geometry(frame, views[i]));
  return k;
}

// This frame's own occluder interval ends at the file's back layer, or at the thickness.
inline float own_back_depth(const MultiViewInputs& in, const MultiViewSettings& s, int x, int y, float front) {
  if (in.depth_back_view == nullptr || in.depth_back_view->empty()) return front + s.thickness_world;
  const float b = in.depth_back_view->ptr<float>(y)[x];
  return b > front ? b : front;
}

// ---- The per-pixel passes (multiview_lanes.cpp: several pixels per instruction) ----

// Per view v, over the foreground pixels of every stride_px-th column of every stride_px-th
// row y: how many it can see (inside its image, in front of its eye), in seen[y nv + v], and
// how many of those it sees free space in front of (the free-space test of multiview.h), in
// contradicted[y nv + v]; nv = k.views.size(), both spans rows x nv, zeroed by the caller.
void count_view_verdicts(const MultiViewInputs& in, const Constants& k, int stride_px, std::span<int64_t> seen,
                         std::span<int64_t> contradicted, int nthreads);

// The back layer of every foreground pixel of `in` (multiview.h, occupancy_from_views), by
// the views of k; +inf on background. `back` CV_32FC1 at the frame's size.
void write_back_layer(const MultiViewInputs& in, const Constants& k, cv::Mat& back, int nthreads);

// PointVerdicts::decided (multiview.h) of each point by the views of k: 1 when decided.
void decide_points(const Constants& k, std::span<const glm::vec3> points_view, std::span<uint8_t> decided);

// decided_bins_behind_surfaces (multiview.h) by the views of k, into `decided` (CV_8UC1 at
// the frame's size, zeroed by the caller).
void write_decided_bins(const MultiViewInputs& in, const Constants& k, float surface_scale, float bin_depth, int bins,
                        cv::Mat& decided, int nthreads);

}  // namespace ssdo::multiview_detail
