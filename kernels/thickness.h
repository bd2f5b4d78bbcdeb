// Occluder thickness from silhouettes: a second depth layer estimated from one depth buffer,
// for frames without a back-face pass.
//
// Screen-space occlusion must guess how far each visible surface extends behind itself. A
// constant guess (AoSettings::thickness_world, 0.5 x radius by default) is too thick for
// poles, plates and leaves, whose halos it paints on what is behind them, and too thin for
// walls, floors and large objects, whose occlusion it cuts short. Here an object is taken to
// be about as deep as it is wide where the pixel sees it: a pixel's thickness is a multiple
// of the world-space distance from it to the nearest silhouette (the near side of a depth
// edge), so thin things are thin, rims are thinnest, and surfaces that no silhouette bounds
// in the picture are solid. The result is a back layer like a back-face pass's
// (GBuffer::depth_back_view), read by GTAO's visibility mask, the raymarch oracle and SSDO's
// occlusion march in its place.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "core/camera.h"

namespace ssdo {

struct SilhouetteThicknessSettings {
  // A pixel lies on a silhouette where one of its four neighbours is background or farther
  // than it by more than this fraction of its depth, (0, inf). Relative, so that the rule
  // keeps its meaning at any scene scale and distance.
  float edge_depth_ratio = 0.1f;
  // Thickness per unit of world-space distance to the nearest silhouette, (0, inf): 4 makes
  // the middle of an object W wide 2 W deep. Both defaults were chosen from coarse steps
  // (1 to 8; 0.02 to 0.2) on the failure suite's synthetic frames and the shared Cycles
  // frames together (docs/accuracy.md, "Thickness from silhouettes").
  float thickness_per_distance = 4.0f;
};

// Empty when the settings are valid, else what is wrong (field, value, range).
std::string validate(const SilhouetteThicknessSettings& s);

// back_depth_view = depth_view + the thickness (along the view axis, scene units) on pixels
// with mask != 0; +inf (solid behind) on background, where no silhouette is in the picture,
// and where the nearest silhouette lies in front of the pixel (another object's rim). The
// distance to a silhouette is Euclidean, in pixels of these images, to a silhouette pixel
// found by an exact distance transform over cells of 2 x 2 pixels (Felzenszwalb &
// Huttenlocher 2012, kernels/distance_transform.h; each cell's first silhouette pixel stands
// for the cell): 0 on silhouette pixels, else at
// most 2 sqrt(2) pixels more than the exact distance (0.24 px more on average over a disc),
// for a quarter of the transform's work. Times the world size of a pixel at the pixel's
// depth (Camera::pixels_per_unit), plus half a pixel: a silhouette pixel is half a pixel
// thick. depth_view CV_32FC1 planar depth, mask CV_8UC1 of its size; back_depth_view is
// allocated CV_32FC1 at that size. The same bits for any nthreads.
void estimate_back_depth(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                         const SilhouetteThicknessSettings& s, cv::Mat& back_depth_view, int nthreads = 0);

}  // namespace ssdo
