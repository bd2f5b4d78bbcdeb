#include "kernels/thickness.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/parallel.h"
#include "core/uninitialized.h"
#include "kernels/distance_transform.h"
#include "kernels/settings_check.h"

namespace ssdo {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int32_t kNone = -1;
// Cell rows per strip of mark_silhouettes: each strip computes the shown depth of one or
// two rows more than its own (the row above it, and the one below), 6% at 16 cell rows.
constexpr int kStripCellRows = 16;

// Row y of the depth a neighbour shows to the silhouette test, into out (w floats): the
// foreground's own, +inf where the pixel shows background (mask 0 with a 4-neighbour of
// mask 0), -inf on a lone background pixel inside the foreground: that is a dropped sample
// (a non-finite value the reader masked), not a view past an object, and makes no
// silhouette.
void shown_row(const cv::Mat& depth_view, const cv::Mat& mask, int y, float* out) {
  const int w = mask.cols, h = mask.rows;
  const float* d = depth_view.ptr<float>(y);
  const uint8_t* m = mask.ptr<uint8_t>(y);
  // Off-image neighbours count as foreground (unknown): the pixel's own row stands in.
  const uint8_t* m_up = mask.ptr<uint8_t>(y > 0 ? y - 1 : y);
  const uint8_t* m_down = mask.ptr<uint8_t>(y + 1 < h ? y + 1 : y);
  const uint8_t up = y > 0, down = y + 1 < h;
  const auto shown = [&](int x, bool left_open, bool right_open) {
    const bool open = left_open | right_open | (up & !m_up[x]) | (down & !m_down[x]);
    const float depth = d[x];  // loaded whatever the mask, so that the loop has no branch
    out[x] = m[x] ? depth : open ? kInf : -kInf;
  };
  shown(0, false, w > 1 && !m[std::min(1, w - 1)]);
  for (int x = 1; x < w - 1; ++x) shown(x, !m[x - 1], !m[x + 1]);  // the interior, without clamps
  if (w > 1) shown(w - 1, !m[w - 2], false);
}

// The silhouette pixels of a row into edge (1 = on a silhouette): foreground pixels (mask
// m) with a 4-neighbour whose shown depth (shown_row: d of the row, d_up and d_down of the
// rows above and below) is farther than them by more than edge_depth_ratio of their depth,
// background included. Neighbours outside the image are unknown, not background: the
// frame's border is no silhouette (off-image rows are the row itself).
void silhouettes_of_row(const float* d_up, const float* d, const float* d_down, const uint8_t* m, int w,
                        float edge_depth_ratio, uint8_t* edge) {
  const float step = 1.0f + edge_depth_ratio;
  const auto test = [&](int x, int xl, int xr) {
    const float farther = d[x] * step;
    const bool behind = (d[xl] > farther) | (d[xr] > farther) | (d_up[x] > farther) | (d_down[x] > farther);
    edge[x] = uint8_t((m[x] != 0) & behind);
  };
  test(0, 0, std::min(1, w - 1));
  for (int x = 1; x < w - 1; ++x) test(x, x - 1, x + 1);  // the interior, without clamps
  if (w > 1) test(w - 1, w - 2, w - 1);
}

// Silhouette pixels standing for cells: a cell's representative is the first of its
// silhouette pixels in row-major order, x = kNone where it has none; behind_depth is the depth
// beyond which a pixel lies behind it (its depth times 1 + edge_depth_ratio: a pixel nearer
// than that whose nearest silhouette it is sees another object's rim).
// Unzeroed: every entry is written before it is read.
struct Representatives {
  UninitializedVector<int32_t> x, y;
  UninitializedVector<float> behind_depth;
  explicit Representatives(size_t n = 0) : x(n), y(n), behind_depth(n) {}
};

// Cell row cy's representatives (from `first` in each array) and their marks in
// silhouette_cell's row: pixel rows y0 and y1 (the same row at the image's last odd row), a
// cell's columns 2 cx and 2 cx + 1 (the same column at the last odd column). A cell's four
// pixels decide by selects, without branches.
void cell_representatives(const cv::Mat& depth_view, const cv::Mat& edge, int y0, int y1, float behind_step,
                          Representatives& rep, size_t first, uint8_t* has_silhouette) {
  const int w = edge.cols, cells_x = (w + 1) / 2;
  const uint8_t* e0 = edge.ptr<uint8_t>(y0);
  const uint8_t* e1 = edge.ptr<uint8_t>(y1);
  const float* d0 = depth_view.ptr<float>(y0);
  const float* d1 = depth_view.ptr<float>(y1);
  int32_t* rep_x = rep.x.data() + first;
  int32_t* rep_y = rep.y.data() + first;
  float* rep_behind = rep.behind_depth.data() + first;
  const auto cell = [&](int cx, int x0, int x1) {
    const bool a = e0[x0] != 0, b = e0[x1] != 0, c = e1[x0] != 0, d = e1[x1] != 0;
    const float depth_a = d0[x0], depth_b = d0[x1], depth_c = d1[x0], depth_d = d1[x1];
    // The first of a, b, c, d: in the top row where a or b, in the left column where a, or
    // c without b.
    const bool any = a | b | c | d, top = a | b, left = a | (!b & c);
    rep_x[cx] = any ? (left ? x0 : x1) : kNone;
    rep_y[cx] = any ? (top ? y0 : y1) : kNone;
    rep_behind[cx] = any ? (top ? (a ? depth_a : depth_b) : (c ? depth_c : depth_d)) * behind_step : 0.0f;
    has_silhouette[cx] = any ? 255 : 0;
  };
  for (int cx = 0; cx < w / 2; ++cx) cell(cx, 2 * cx, 2 * cx + 1);
  if (w % 2 != 0) cell(cells_x - 1, w - 1, w - 1);
}

// The silhouette pixels (edge = 1) of the image, and each cell of 2 x 2 pixels' representative
// (`representative`, row-major over the cells); `silhouette_cell` 255 where the cell has one.
// Cells are independent: the threads take rows of them, each with the shown depth of the rows
// it reads in a ring of three (a row's neighbours above and below), computed again for the row
// above a strip.
void mark_silhouettes(const cv::Mat& depth_view, const cv::Mat& mask, float edge_depth_ratio, cv::Mat& edge,
                      Representatives& representative, cv::Mat& silhouette_cell, int nthreads) {
  const int w = depth_view.cols, h = depth_view.rows;
  edge.create(depth_view.size(), CV_8UC1);
  silhouette_cell.create((h + 1) / 2, (w + 1) / 2, CV_8UC1);
  const int cells_x = silhouette_cell.cols;
  representative = Representatives(silhouette_cell.total());
  parallel_rows(cv::Range(0, silhouette_cell.rows), nthreads, [&](const cv::Range& cell_rows) {
    std::vector<float> ring(size_t(3) * size_t(w));
    const auto shown = [&](int y) { return ring.data() + size_t(y % 3) * size_t(w); };
    const int y_first = 2 * cell_rows.start, y_end = std::min(2 * cell_rows.end, h);
    if (y_first > 0) shown_row(depth_view, mask, y_first - 1, shown(y_first - 1));
    shown_row(depth_view, mask, y_first, shown(y_first));
    for (int y = y_first; y < y_end; ++y) {
      if (y + 1 < h) shown_row(depth_view, mask, y + 1, shown(y + 1));
      silhouettes_of_row(shown(y > 0 ? y - 1 : y), shown(y), shown(y + 1 < h ? y + 1 : y), mask.ptr<uint8_t>(y), w,
                         edge_depth_ratio, edge.ptr<uint8_t>(y));
    }
    for (int cy = cell_rows.start; cy < cell_rows.end; ++cy)
      cell_representatives(depth_view, edge, 2 * cy, std::min(2 * cy + 1, h - 1), 1.0f + edge_depth_ratio,
                           representative, size_t(cy) * size_t(cells_x), silhouette_cell.ptr<uint8_t>(cy));
  }, kStripCellRows);
}

// What a pixel's thickness takes: scene units per pixel at depth d, units_per_px_0 +
// units_per_px_slope d; the thickness per unit of distance; 1 + edge_depth_ratio.
struct PixelThickness {
  float units_per_px_0, units_per_px_slope, thickness_per_distance, behind_step;
};

// Row y of back_depth_view (estimate_back_depth) from its depth d, mask m, silhouette pixels
// on_edge and its nearest silhouettes' representatives: d + thickness_per_distance x (the
// distance to the representative, a silhouette pixel's to itself 0, + 1/2) x the scene units
// per pixel, or +inf on background, with no silhouette in the picture, or behind the nearest
// silhouette's pixel (another object's rim). Without a branch, so that the loop vectorises.
// The squared distance is exact in Int and rounded once to float: int32_t where both sides of
// the image are below 2^15 (so that it stays below 2^31), else int64_t, the same value.
template <class Int>
void pixel_thickness_row(const float* d, const uint8_t* m, const uint8_t* on_edge, const Representatives& nearest,
                         const PixelThickness& k, int y, int w, float* back) {
  const int32_t* nearest_x = nearest.x.data();
  const int32_t* nearest_y = nearest.y.data();
  const float* nearest_behind = nearest.behind_depth.data();
  for (int x = 0; x < w; ++x) {
    // Every value loaded, then selected (a load under a condition would keep the branch).
    const float depth = d[x], nearest_behind_depth = nearest_behind[x];
    const Int to_x = Int(x) - nearest_x[x], to_y = Int(y) - nearest_y[x];
    const bool edge = on_edge[x] != 0;
    const Int dx = edge ? 0 : to_x, dy = edge ? 0 : to_y;
    const float behind_depth = edge ? depth * k.behind_step : nearest_behind_depth;
    const bool has = (m[x] != 0) & (edge | (nearest_x[x] != kNone)) & !(behind_depth < depth);
    const float distance_px = std::sqrt(float(dx * dx + dy * dy));
    const float units_per_px = k.units_per_px_0 + k.units_per_px_slope * depth;
    const float thick = depth + k.thickness_per_distance * (distance_px + 0.5f) * units_per_px;
    back[x] = has ? thick : kInf;
  }
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
  const int w = depth_view.cols;
  // Scene units per pixel at planar depth d (square pixels: the vertical size): the inverse
  // of Camera::pixels_per_unit, linear in d (clip w is), so taken as a + b d without a
  // division per pixel.
  const float units_per_px_0 = 1.0f / camera.pixels_per_unit(0.0f).y;
  const float units_per_px_slope = 1.0f / camera.pixels_per_unit(1.0f).y - units_per_px_0;
  const PixelThickness pixel_rows{units_per_px_0, units_per_px_slope, s.thickness_per_distance,
                                  1.0f + s.edge_depth_ratio};
  cv::Mat edge, silhouette_cell, nearest_cell;
  Representatives representative;
  mark_silhouettes(depth_view, mask, s.edge_depth_ratio, edge, representative, silhouette_cell, nthreads);
  const int cells_x = silhouette_cell.cols;
  // Squared distances in int32_t below 2^15 pixels a side (pixel_thickness_row).
  const bool small_image = w < (1 << 15) && depth_view.rows < (1 << 15);
  const auto pixel_row = small_image ? pixel_thickness_row<int32_t> : pixel_thickness_row<int64_t>;
  back_depth_view.create(depth_view.size(), CV_32FC1);
  // The pixel rows of a strip of cell rows, as soon as the transform's row pass has written
  // their nearest silhouette cells: per cell row, the representatives of those cells by pixel
  // column, then the rows without a branch (pixel_thickness_row).
  squared_distance_to_marks(silhouette_cell, nthreads, &nearest_cell, [&](const cv::Range& cell_rows) {
    // The representative of each pixel column's nearest silhouette cell (x = kNone and
    // behind_depth -inf where there is none).
    Representatives nearest(static_cast<size_t>(w));
    for (int cy = cell_rows.start; cy < cell_rows.end; ++cy) {
      const cv::Point* cell_nearest = nearest_cell.ptr<cv::Point>(cy);
      for (int x = 0; x < w; ++x) {
        const cv::Point cell = cell_nearest[x / 2];
        const size_t c = size_t(cell.y) * size_t(cells_x) + size_t(cell.x);
        const bool none = cell.x < 0;
        nearest.x[size_t(x)] = none ? kNone : representative.x[c];
        nearest.y[size_t(x)] = none ? kNone : representative.y[c];
        nearest.behind_depth[size_t(x)] = none ? -kInf : representative.behind_depth[c];
      }
      for (int y = 2 * cy; y < std::min(2 * cy + 2, depth_view.rows); ++y)
        pixel_row(depth_view.ptr<float>(y), mask.ptr<uint8_t>(y), edge.ptr<uint8_t>(y), nearest, pixel_rows, y, w,
                  back_depth_view.ptr<float>(y));
    }
  });
}

}  // namespace ssdo
