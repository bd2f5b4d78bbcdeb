// View-space positions from planar depth and the camera (computed once per frame).
#pragma once

#include <opencv2/core.hpp>

#include "core/camera.h"

namespace ssdo {

// position_view(i, j) = camera.view_from_pixel_depth((i + 0.5, j + 0.5), depth_view(i, j))
// for pixels with mask != 0, (0, 0, 0) elsewhere. Output CV_32FC3 (x, y, z), allocated
// when empty or of the wrong size; only `roi` (empty = all) is written.
void view_positions_from_depth(const cv::Mat& depth_view, const cv::Mat& mask,
                               const Camera& camera, cv::Mat& position_view,
                               cv::Rect roi = {}, int nthreads = 0);

// The checks and the output of a per-pixel image of view-space vectors computed from depth
// (the positions above, the normals of normals.h): depth_view CV_32FC1 and mask CV_8UC1 of
// one size; out allocated CV_32FC3 at that size when empty or of another size or type.
// Returns roi resolved against the size (empty = all).
cv::Rect prepare_view_vectors(const cv::Mat& depth_view, const cv::Mat& mask, cv::Mat& out, cv::Rect roi);

}  // namespace ssdo
