// View-space normals reconstructed from planar depth, for frames without a normal pass
// (and for pixels whose stored normal is unusable).
#pragma once

#include <opencv2/core.hpp>

#include "core/camera.h"

namespace ssdo {

// normal_view(i, j): unit view-space normal of the surface seen at pixel (i, j), facing the
// camera, from the planar depth map (CV_32FC1, scene units) and the camera; (0, 0, 0)
// where mask (CV_8UC1) is 0. Output CV_32FC3 (x, y, z), allocated when empty or of the
// wrong size; only `roi` (empty = all) is written; reads depth anywhere.
//
// Method: the surface tangents along x and y are one-sided differences of view-space
// positions. On each axis the side is chosen so that the difference never crosses a depth
// edge: the side whose neighbour continues the centre's depth best, i.e. the smaller
// |2 q(+-1) - q(+-2) - q(0)| (second-order extrapolation error, as in "accurate view-space
// normal reconstruction" by comparing one-sided slopes), where q = 1/depth for perspective
// cameras (1/depth is affine in screen space over a plane, so a plane scores exactly 0)
// and q = depth for orthographic ones. When the two errors agree within a factor of 2
// (a plane, or a smooth surface where both are curvature terms) the central difference is
// used instead: second-order accurate, and it cannot straddle an edge, since an edge makes
// one error far larger than the other. Where a side lacks its second neighbour, the
// smaller first difference |q(+-1) - q(0)| decides. n = cross(t_y, t_x), flipped to face
// the eye. A pixel with no valid neighbour on an axis gets the normal facing the eye
// (-view ray), the only unbiased guess.
void reconstruct_normals_from_depth(const cv::Mat& depth_view, const cv::Mat& mask,
                                    const Camera& camera, cv::Mat& normal_view,
                                    cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
