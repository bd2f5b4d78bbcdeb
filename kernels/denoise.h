// Edge-aware denoising of screen-space terms (AO, SSDO light) and the plain box blur of
// the seed projects, for comparison.
#pragma once

#include <span>
#include <string>

#include <opencv2/core.hpp>

namespace ssdo {

struct DenoiseSettings {
  // Half width of the kernel, pixels, [0, 32]: each pass reads the taps k tap_spacing_px
  // pixels apart with |k tap_spacing_px| <= radius_px (2 * radius_px + 1 taps at spacing 1).
  // 4 covers a 4x4 noise tile plus a pixel either side.
  int radius_px = 4;
  // Pixels between two taps of a pass, [1, 4]. 1 (default) reads every pixel. An image
  // upsampled from a grid of divisor D holds one independent estimate per D x D pixels, so
  // taps D apart see every estimate of the footprint (scaled_to_grid).
  int tap_spacing_px = 1;
  // Standard deviation of the Gaussian spatial weight, pixels, (0, inf). 2.5 keeps the
  // outermost tap of radius 4 at weight exp(-16 / 12.5) = 0.28.
  float sigma_px = 2.5f;
  // Depth tolerance relative to the two pixels' depths, (0, inf): a tap whose depth
  // differs by |d_tap - d| >= depth_tolerance_relative * h, h the harmonic mean of d and
  // d_tap, gets weight 0 (hard cut, so nothing crosses a silhouette); below it the weight
  // falls linearly from 1. The same for either pixel of a pair (a tap's weight is
  // computed once per pair). 0.05 is ~5x the depth change across 4 px of a surface at 80
  // deg from the view at 640 px.
  float depth_tolerance_relative = 0.05f;
  // Exponent of the normal weight max(0, dot(n, n_tap))^normal_power, [0, 256]. 16 halves
  // the weight at ~17 deg and cuts creases of 45 deg and more to < 0.004.
  float normal_power = 16.0f;
};

// Returns an empty string when valid, else the field, value and range.
std::string validate(const DenoiseSettings& s);

// The settings for a term computed on a grid of resolution_divisor (1 = every pixel, 2 =
// the half-resolution grid, kernels/half_resolution.h) and upsampled: radius_px, sigma_px
// and tap_spacing_px times the divisor (the radius at most 32, the spacing at most 4). Each
// estimate of a half-grid term, with its own noise, covers 2 x 2 pixels once upsampled, so
// the same footprint in pixels holds a quarter of the independent estimates; doubling it
// restores their count (measured on the shared frames against the SSDO oracle:
// docs/performance.md, "Directions against the denoise's footprint"). Taps as far apart as
// the estimates keep the taps per pass of the full-resolution footprint: the pixels between
// them are blends of the same estimates.
DenoiseSettings scaled_to_grid(const DenoiseSettings& s, int resolution_divisor);

// The pixels the blur of `roi` reads in an image of `size`: roi grown by the farthest tap,
// floor(radius_px / tap_spacing_px) x tap_spacing_px, clipped to the image. A caller that
// computes the source for the blur computes it there.
cv::Rect denoise_reads(const cv::Rect& roi, const DenoiseSettings& s, const cv::Size& size);

// Depth- and normal-aware separable bilateral blur (a horizontal pass, then a vertical
// pass over its result) of a CV_32FC1 or CV_32FC3 image. Tap weight:
//   g(k) * max(0, 1 - |d_tap - d| / (tol h)) * max(0, n . n_tap)^power,
// h = 2 / (1 / d + 1 / d_tap) the harmonic mean of the two depths (the weight is symmetric
// in the pixel and its tap); k the tap's offset in pixels (a multiple of tap_spacing_px,
// |k| <= radius_px), g the Gaussian of sigma_px; taps outside the image or with mask 0
// weigh 0. The centre always weighs 1 (g(0), its depth weight and the lobe of its unit
// normal with itself), so the weight sum is never 0. Pixels with mask 0 are copied
// unchanged. depth_view CV_32FC1 planar (> 0 on foreground), normal_view CV_32FC3 unit,
// mask CV_8UC1 (255 = foreground). dst is allocated like src when needed and only roi
// (empty = all) is written; dst must not share memory with src.
void denoise_bilateral(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
                       const cv::Mat& mask, const DenoiseSettings& settings, cv::Mat& dst,
                       cv::Rect roi = {}, int nthreads = 0);

// The same blur of several images of one frame in one pass (e.g. AO and the two SSDO
// terms): the tap weights depend only on depth, normals and mask, so they are computed
// once for every channel instead of once per image. Each result is bit-identical to
// denoise_bilateral of that image alone. srcs[i] CV_32FC1 or CV_32FC3, all of the guides'
// size; dsts[i] as dst above (distinct, none sharing memory with a source).
void denoise_bilateral(std::span<const cv::Mat* const> srcs, const cv::Mat& depth_view,
                       const cv::Mat& normal_view, const cv::Mat& mask,
                       const DenoiseSettings& settings, std::span<cv::Mat* const> dsts,
                       cv::Rect roi = {}, int nthreads = 0);

// The SSAO blur of the seed projects: each pixel becomes the mean of the 4x4 block of
// pixels at offsets [-2, 1] x [-2, 1] around it (matching a 4x4 noise tile), counting only
// taps inside the image. Ignores depth, normals and mask. CV_32FC1 or CV_32FC3; dst as
// above.
void box_blur_4x4(const cv::Mat& src, cv::Mat& dst, cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
