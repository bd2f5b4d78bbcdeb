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

}  // namespace ssdo
