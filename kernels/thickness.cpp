#include "kernels/thickness.h"

#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/parallel.h"
#include "kernels/settings_check.h"

namespace ssdo {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// 0 on silhouette pixels (a foreground pixel with a background or farther 4-neighbour), 1
// elsewhere: the zeros the distance transform measures to. Neighbours outside the image
// are unknown, not background: the frame's border is no silhouette.
void mark_silhouettes(const cv::Mat& depth_view, const cv::Mat& mask, float edge_depth_ratio, cv::Mat& not_edge,
                      int nthreads) {
  const int w = depth_view.cols, h = depth_view.rows;
  not_edge.create(depth_view.size(), CV_8UC1);
  parallel_rows(cv::Range(0, h), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* d = depth_view.ptr<float>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* d_up = y > 0 ? depth_view.ptr<float>(y - 1) : nullptr;
      const float* d_down = y + 1 < h ? depth_view.ptr<float>(y + 1) : nullptr;
      const uint8_t* m_up = y > 0 ? mask.ptr<uint8_t>(y - 1) : nullptr;
      const uint8_t* m_down = y + 1 < h ? mask.ptr<uint8_t>(y + 1) : nullptr;
      uint8_t* out = not_edge.ptr<uint8_t>(y);
      for (int x = 0; x < w; ++x) {
        out[x] = 1;
        if (!m[x]) continue;
        const float farther = d[x] * (1.0f + edge_depth_ratio);
        auto behind = [&](const float* dn, const uint8_t* mn, int xn) { return !mn[xn] || dn[xn] > farther; };
        const bool edge = (x > 0 && behind(d, m, x - 1)) || (x + 1 < w && behind(d, m, x + 1)) ||
                          (d_up && behind(d_up, m_up, x)) || (d_down && behind(d_down, m_down, x));
        if (edge) out[x] = 0;
      }
    }
  });
}

}  // namespace

std::string validate(const SilhouetteThicknessSettings& s) {
  if (!(s.edge_depth_ratio > 0.0f) || !std::isfinite(s.edge_depth_ratio))
    return detail::out_of_range("edge_depth_ratio", s.edge_depth_ratio, "(0, inf)");
  if (!(s.thickness_per_distance > 0.0f) || !std::isfinite(s.thickness_per_distance))
    return detail::out_of_range("thickness_per_distance", s.thickness_per_distance, "(0, inf)");
  return {};
}

void estimate_back_depth(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                         const SilhouetteThicknessSettings& s, cv::Mat& back_depth_view, int nthreads) {
  assert(depth_view.type() == CV_32FC1 && mask.type() == CV_8UC1 && mask.size() == depth_view.size());
  assert(validate(s).empty());
  cv::Mat not_edge, distance_px, nearest;
  mark_silhouettes(depth_view, mask, s.edge_depth_ratio, not_edge, nthreads);
  // Each silhouette pixel's depth by its label: the distance transform gives each of the
  // `edges` silhouette pixels its own label in 1 .. edges, and every pixel the label of its
  // nearest one.
  const size_t edges = not_edge.total() - size_t(cv::countNonZero(not_edge));
  const bool any_edge = edges > 0;
  std::vector<float> silhouette_depth(edges + 1, 0.0f);
  if (any_edge) {
    cv::distanceTransform(not_edge, distance_px, nearest, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
    for (int y = 0; y < not_edge.rows; ++y)
      for (int x = 0; x < not_edge.cols; ++x)
        if (!not_edge.at<uint8_t>(y, x))
          silhouette_depth.at(size_t(nearest.at<int32_t>(y, x))) = depth_view.at<float>(y, x);
  }
  back_depth_view.create(depth_view.size(), CV_32FC1);
  parallel_rows(cv::Range(0, depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* d = depth_view.ptr<float>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      float* back = back_depth_view.ptr<float>(y);
      for (int x = 0; x < depth_view.cols; ++x) {
        back[x] = kInf;
        if (!m[x] || !any_edge) continue;
        // A nearest silhouette in front of the pixel is another object's rim (a pole before a
        // wall): it says nothing of this surface's depth, which stays solid.
        const float edge_depth = silhouette_depth[size_t(nearest.at<int32_t>(y, x))];
        if (edge_depth * (1.0f + s.edge_depth_ratio) < d[x]) continue;
        // Scene units per pixel at this depth (square pixels: the vertical size).
        const float units_per_px = 1.0f / camera.pixels_per_unit(d[x]).y;
        back[x] = d[x] + s.thickness_per_distance * (distance_px.at<float>(y, x) + 0.5f) * units_per_px;
      }
    }
  });
}

}  // namespace ssdo
