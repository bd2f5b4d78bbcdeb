// A shot's frames computed with temporal filtering (kernels/temporal.h, FrameRequest::
// temporal_per_side) and measured: flicker (the reprojected frame-to-frame change,
// kernels/metrics.h) and MAE of a denoised term against a reference. The measurement of
// tests/accuracy/temporal_accuracy_test.cpp (a synthetic shot of the reference ray caster)
// and of the shared orbit (against Cycles).
#pragma once

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kernels/metrics.h"
#include "service/pipeline.h"

namespace ssdo::shot {

// Milliseconds per frame since t0, over n frames.
inline double ms_per_frame(std::chrono::steady_clock::time_point t0, size_t n) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / double(n);
}

// Every frame's raw terms (compute_raw_frame), computed once for every K; ms: their mean time.
inline std::vector<RawFrame> raw_frames(const std::vector<const GBuffer*>& frames, const FrameRequest& request,
                                        double& ms) {
  std::vector<RawFrame> raws;
  const auto t0 = std::chrono::steady_clock::now();
  for (const GBuffer* g : frames) raws.push_back(compute_raw_frame(GBuffer(*g), request));
  ms = ms_per_frame(t0, frames.size());
  return raws;
}

// Every frame computed alone, as the product computes a frame without temporal neighbours
// (compute_frame: the half grid's terms denoised on the grid); ms: the mean time of a frame.
inline std::vector<ComputedFrame> lone_frames(const std::vector<const GBuffer*>& frames, const FrameRequest& request,
                                              double& ms) {
  std::vector<ComputedFrame> out;
  const auto t0 = std::chrono::steady_clock::now();
  for (const GBuffer* g : frames) out.push_back(compute_frame(*g, request));
  ms = ms_per_frame(t0, frames.size());
  return out;
}

// Frame t finished with the frames t-k..t+k of the shot (those that exist) as temporal
// neighbours, nearest first per side as the service orders them; ms: the mean time of a
// frame's finish.
inline std::vector<ComputedFrame> finished_frames(const std::vector<RawFrame>& raws, int k,
                                                  const FrameRequest& request, double& ms) {
  std::vector<ComputedFrame> out;
  const int n = int(raws.size());
  const auto t0 = std::chrono::steady_clock::now();
  for (int t = 0; t < n; ++t) {
    std::vector<RawFrame> parts;
    for (int d = 1; d <= k; ++d)
      for (int u : {t - d, t + d})
        if (u >= 0 && u < n) parts.push_back(temporal_part(raws[size_t(u)]));
    std::vector<const RawFrame*> neighbours;
    for (const RawFrame& p : parts) neighbours.push_back(&p);
    FrameRequest r = request;
    r.temporal_per_side = k;
    out.push_back(finish_frame(RawFrame(raws[size_t(t)]), neighbours, r));
  }
  ms = ms_per_frame(t0, size_t(n));
  return out;
}

struct TemporalMeasured {
  double flicker = 0;            // mean reprojected change of the term between consecutive frames
  double reference_flicker = 0;  // the reference's own over the same pixels
  double mae = 0;                // mean over frames of the frame's MAE against its reference
};

// `term` of each finished frame against references[t] (the term's type; a one-channel
// reference stands for every channel of an RGB term), flicker over the pairs (t, t+1) both
// ways.
inline TemporalMeasured measure_shot(const std::vector<ComputedFrame>& computed, const std::vector<const GBuffer*>& frames,
                                     const std::vector<cv::Mat>& references, const std::string& term) {
  TemporalMeasured m;
  const size_t n = frames.size();
  std::vector<cv::Mat> refs(n);
  for (size_t t = 0; t < n; ++t) {
    const cv::Mat& estimate = *computed[t].find(term);
    refs[t] = references[t];
    if (estimate.channels() == 3 && refs[t].channels() == 1) cv::merge(std::vector<cv::Mat>(3, references[t]), refs[t]);
    m.mae += compare_images(estimate, refs[t], frames[t]->mask).mae / double(n);
  }
  FlickerAccumulator flicker;
  auto frame = [&](size_t t) {
    const GBuffer& g = *frames[t];
    return FlickerFrame{*computed[t].find(term), refs[t], g.depth_view, g.normal_view, g.mask, g.camera};
  };
  for (size_t t = 0; t + 1 < n; ++t) {
    flicker.add(frame(t), frame(t + 1));
    flicker.add(frame(t + 1), frame(t));
  }
  m.flicker = flicker.mean_change();
  m.reference_flicker = flicker.reference_change();
  return m;
}

}  // namespace ssdo::shot
