// A shot's frames computed alone and with their neighbours as extra views (GBuffer::views,
// kernels/multiview.h): the measurement of tests/accuracy/multiview_accuracy_test.cpp (the
// shared orbit, against Cycles) and tests/accuracy/sequence_accuracy_test.cpp (a synthetic
// shot, against the reference ray caster).
#pragma once

#include <algorithm>
#include <chrono>
#include <optional>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kernels/metrics.h"
#include "service/pipeline.h"
#include "service/sequence_context.h"
#include "service/view_selection.h"

namespace ssdo::shot {

// Frame u of a shot (0 <= u < frames), and the name its view carries in notes.
using FrameOf = std::function<const GBuffer&(int u)>;
using NameOf = std::function<std::string(int u)>;

// Frame t with the frames t-k..t+k that lie inside the shot (0..frames-1) as views: the
// window a shot's frame has when every neighbour within K is used (the service chooses
// among them by parallax: service/view_selection.h). k = 0: the frame alone.
inline GBuffer with_views(int t, int k, int frames, const FrameOf& frame, const NameOf& name) {
  GBuffer g = frame(t);
  for (int u = std::max(0, t - k); u <= std::min(frames - 1, t + k); ++u)
    if (u != t) g.views.push_back({frame(u).camera, frame(u).depth_view, name(u)});
  return g;
}

// Frame t with the views the service picks for `--views k` (service/view_selection.h: by
// parallax at the frame's median foreground depth, among the frames within
// kCandidateFramesPerView x k of it inside the shot). k = 0: the frame alone.
inline GBuffer with_chosen_views(int t, int k, int frames, const FrameOf& frame, const NameOf& name) {
  GBuffer g = frame(t);
  std::vector<ViewCandidate> candidates;
  const int window = kCandidateFramesPerView * k;
  for (int u = std::max(0, t - window); u <= std::min(frames - 1, t + window); ++u)
    if (u != t)
      candidates.push_back({name(u), u - t, true, frame(u).width_px(), frame(u).height_px(), frame(u).camera.view_to_world});
  ViewSelectionSettings settings;
  settings.views_per_side = k;
  const ViewChoice choice = select_views(g.camera.view_to_world, g.width_px(), g.height_px(),
                                         median_foreground_depth(g.depth_view, g.mask), candidates, settings);
  for (size_t i : choice.chosen) {
    const int u = t + candidates[i].frame_offset;
    g.views.push_back({frame(u).camera, frame(u).depth_view, name(u)});
  }
  return g;
}

struct Measured {
  double ms = 0;          // compute_frame, the occupancy pass of the views included
  ErrorStats whole;       // over the frame's compared pixels
  ErrorStats border;      // over the compared pixels of the border band (when one is given)
};

// AO only (no composite), the method's preset at radius_world (with `thickness_model` in
// place of the preset's when given).
inline FrameRequest ao_request(AoMethod method, Preset preset, float radius_world,
                               std::optional<ThicknessModel> thickness_model = std::nullopt) {
  FrameRequest request;
  request.ao = ao_preset(method, preset);
  request.ao.radius_world = radius_world;
  if (thickness_model) request.ao.thickness_model = *thickness_model;
  request.terms.composite = false;
  return request;
}

// The denoised AO (`ao_denoised`) of `g` (ao_request), against `reference` (CV_32FC1) over
// `mask` and over `border_mask` (CV_8UC1, may be empty).
inline Measured measure_denoised_ao(const GBuffer& g, AoMethod method, Preset preset, float radius_world,
                                    const cv::Mat& reference, const cv::Mat& mask,
                                    const cv::Mat& border_mask = {},
                                    std::optional<ThicknessModel> thickness_model = std::nullopt) {
  const auto t0 = std::chrono::steady_clock::now();
  const ComputedFrame out = compute_frame(g, ao_request(method, preset, radius_world, thickness_model));
  Measured m;
  m.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const cv::Mat& ao = *out.find("ao_denoised");
  m.whole = compare_images(ao, reference, mask);
  if (!border_mask.empty()) m.border = compare_images(ao, reference, border_mask);
  return m;
}

}  // namespace ssdo::shot
