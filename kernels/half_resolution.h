// Half-resolution evaluation of a per-pixel kernel (AO, SSDO): the kernel runs on a grid
// of half the width and height (a quarter of the pixels), and a depth- and normal-aware
// upsample brings its outputs back to full resolution.
//
// Texel (i, j) of the half grid stands for the 2x2 block of pixels (2i.., 2j..) and takes
// the first foreground pixel of the block in the order (0,0), (1,0), (0,1), (1,1): its
// exact depth, normal, view-space position and extra inputs (no averaging, which would
// invent points between a silhouette and the background). The camera keeps its projection
// with the half grid's size, so a kernel projecting radii and points sees the same scene
// at half the pixels.
//
// Upsample (joint bilateral over the 2x2 nearest texels; Kopf et al. 2007, "Joint
// Bilateral Upsampling", SIGGRAPH): bilinear weights x exp(-|dz| / (tol z)) x
// max(0, n . n_texel)^4, tol = kUpsampleDepthRelative. When all four weigh ~0 (a pixel
// whose surface no nearby texel took), the texel of the 4x4 neighbourhood closest in depth
// is copied; with no foreground texel there, the image's fallback value is written.
#pragma once

#include <span>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"

namespace ssdo {

struct HalfGrid {
  cv::Mat depth_view, normal_view, mask;  // as the full-resolution inputs
  // The source pixels' view-space positions (the full-resolution positions' or, without
  // them, view_positions_from_depth's values); empty when built without positions.
  cv::Mat position_view;
  std::vector<cv::Mat> extras;  // each extra input's value at the texel (0 where none)
  cv::Mat source;               // CV_32SC2: the full-resolution pixel taken, (-1, -1) if none
  Camera camera;                // the full camera with the half grid's size
  // The upsample's texel weights of the full-resolution pixels of upsample_roi
  // (build_upsample_weights; CV_32FC4, the full size, weight k of texel k of the 2x2 block
  // the pixel reads, 0 on masked texels), for kernels of one frame that share the grid:
  // they depend on the guides only, so every upsample from the grid reuses them. Empty:
  // each upsample computes them itself (the same values).
  cv::Mat upsample_weights;
  cv::Rect upsample_roi;
};

// The full-resolution views of one frame (CV_32FC1 depth, +inf on background; CV_32FC3
// normal and view positions, positions may be empty for kernels that do not read them;
// CV_8UC1 mask).
struct FullGrid {
  const cv::Mat& depth_view;
  const cv::Mat& normal_view;
  const cv::Mat& position_view;
  const cv::Mat& mask;
  const Camera& camera;
};

// Builds the whole half grid (kernels read taps anywhere on it, whatever the roi). Each
// extra is a CV_32F image of the full size (any channel count) or empty (stays empty).
// with_positions: the texels' positions, copied from full.position_view or, when that is
// empty, computed from the depth at the source pixels only (a full-resolution position
// image is not needed by kernels that run on the grid).
void build_half_grid(const FullGrid& full, std::span<const cv::Mat* const> extras, HalfGrid& half,
                     int nthreads = 0, bool with_positions = true);

// The half grid a kernel runs on: `shared` (the frame's, checked to be of the full
// grid's half size, with positions when `need_positions`) or, when null, `own` built here
// (with positions when `need_positions`).
const HalfGrid& shared_or_own_half_grid(const FullGrid& full, const HalfGrid* shared, HalfGrid& own,
                                        bool need_positions, int nthreads = 0);

// Each texel's value of a full-resolution image: the value at the pixel the texel took
// (HalfGrid::source), 0 on texels that took none. `full_image` CV_32F of any channel
// count and the full size; `half_image` is allocated at the grid's size.
void sample_at_texels(const HalfGrid& half, const cv::Mat& full_image, cv::Mat& half_image,
                      int nthreads = 0);

// exp(x), x <= 0, as the upsample weights evaluate their depth term exp(-|dz| / (tol z)):
// libmvec's vector expf where the kernels are built with AVX2 (within 3 ulp of std::exp),
// else std::exp.
float upsample_depth_falloff(float x);

// Computes and keeps in `half` the upsample weights of the full-resolution roi (empty =
// all), for a grid that several kernels of one frame upsample from.
void build_upsample_weights(const FullGrid& full, HalfGrid& half, cv::Rect roi = {}, int nthreads = 0);

// The texels the upsample of the full-resolution roi reads.
cv::Rect half_grid_roi(const cv::Rect& full_roi, const cv::Size& full_size);

// One image to bring to full resolution: `half` (CV_32F, any channels, the half grid's
// size) into `full` (same type, the full size, allocated by the caller). Background pixels
// get `background`, pixels with no foreground texel near get `fallback`.
struct UpsampleImage {
  const cv::Mat& half;
  cv::Mat& full;
  cv::Scalar background;
  cv::Scalar fallback;
};

// Writes the pixels of `roi` of every image, with the grid's kept weights when they cover
// roi (bit-identical to computing them here).
void upsample_from_half_grid(const FullGrid& full, const HalfGrid& half,
                             std::span<const UpsampleImage> images, const cv::Rect& roi,
                             int nthreads = 0);

}  // namespace ssdo
