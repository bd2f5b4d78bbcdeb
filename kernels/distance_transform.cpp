#include "kernels/distance_transform.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/parallel.h"

namespace ssdo {

void lower_envelope(const float* f, int n, float* d, int* nearest, EnvelopeScratch& scratch) {
  constexpr double kInfD = std::numeric_limits<double>::infinity();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::vector<int>& v = scratch.v;
  std::vector<double>& z = scratch.z;
  int k = -1;
  auto rooted = [&](int p) { return double(f[p]) + double(p) * double(p); };
  for (int q = 0; q < n; ++q) {
    if (!(f[q] < kInf)) continue;
    if (k < 0) {
      k = 0, v[0] = q, z[0] = -kInfD, z[1] = kInfD;
      continue;
    }
    // Where q's parabola meets the envelope's last one; those it passes under are dropped.
    double s = (rooted(q) - rooted(v[size_t(k)])) / (2.0 * double(q - v[size_t(k)]));
    while (s <= z[size_t(k)]) --k, s = (rooted(q) - rooted(v[size_t(k)])) / (2.0 * double(q - v[size_t(k)]));
    ++k, v[size_t(k)] = q, z[size_t(k)] = s, z[size_t(k) + 1] = kInfD;
  }
  if (k < 0) {
    std::fill(d, d + n, kInf);
    if (nearest) std::fill(nearest, nearest + n, -1);
    return;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[size_t(k) + 1] < double(q)) ++k;
    const int p = v[size_t(k)];
    d[q] = float(double(q - p) * double(q - p) + double(f[p]));
    if (nearest) nearest[q] = p;
  }
}

namespace {

// Columns per band of the column pass: a band's rows are a few cache lines of each image.
constexpr int kColumnBand = 64;

// The column pass over columns [x0, x1) of binary marks: each pixel's nearest mark in its
// column into row_of (its row, -1 where the column has none) and the squared distance to it
// into d (+inf where none). The lower envelope of the column's parabolas rooted at its marks,
// all at 0, where two consecutive marks' parabolas meet halfway between them, so that a sweep
// down (the nearest mark at or above) and one up (at or below, and the nearer of the two)
// find it; of two marks equally near, the one above, as lower_envelope takes the earlier
// sample at a tie. A row at a time over the band's columns.
void nearest_in_columns(const cv::Mat& marks, int x0, int x1, cv::Mat& d, cv::Mat& row_of) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const int n = x1 - x0;
  std::vector<int32_t> nearest_row(size_t(n), -1);
  for (int y = 0; y < marks.rows; ++y) {
    const uint8_t* m = marks.ptr<uint8_t>(y) + x0;
    int32_t* above = row_of.ptr<int32_t>(y) + x0;
    for (int i = 0; i < n; ++i) above[i] = nearest_row[size_t(i)] = m[i] ? y : nearest_row[size_t(i)];
  }
  std::fill(nearest_row.begin(), nearest_row.end(), -1);
  for (int y = marks.rows - 1; y >= 0; --y) {
    const uint8_t* m = marks.ptr<uint8_t>(y) + x0;
    int32_t* row = row_of.ptr<int32_t>(y) + x0;
    float* dist = d.ptr<float>(y) + x0;
    for (int i = 0; i < n; ++i) {
      const int32_t below = nearest_row[size_t(i)] = m[i] ? y : nearest_row[size_t(i)], above = row[i];
      const int32_t p = above < 0 ? below : below < 0 || y - above <= below - y ? above : below;
      row[i] = p;
      dist[i] = p < 0 ? kInf : float(int64_t(y - p) * int64_t(y - p));
    }
  }
}

}  // namespace

cv::Mat squared_distance_to_marks(const cv::Mat& marks, int nthreads, cv::Mat* nearest,
                                  const std::function<void(const cv::Range&)>& rows_done) {
  CV_Assert(marks.type() == CV_8UC1);
  const int w = marks.cols, h = marks.rows;
  cv::Mat d(marks.size(), CV_32FC1), row_of(marks.size(), CV_32SC1);
  // Columns first (nearest_in_columns), then rows over the columns' results: the squared
  // Euclidean distance is separable, and the nearest mark of a row's pass lies in the column
  // its nearest sample names, at the row that column's pass found.
  parallel_rows(cv::Range(0, (w + kColumnBand - 1) / kColumnBand), nthreads, [&](const cv::Range& bands) {
    for (int b = bands.start; b < bands.end; ++b)
      nearest_in_columns(marks, b * kColumnBand, std::min((b + 1) * kColumnBand, w), d, row_of);
  }, 1);
  if (nearest) nearest->create(marks.size(), CV_32SC2);
  parallel_rows(cv::Range(0, h), nthreads, [&](const cv::Range& rows) {
    const size_t n = static_cast<size_t>(w);
    std::vector<float> f(n);
    std::vector<int> at(n);
    EnvelopeScratch scratch(w);
    for (int y = rows.start; y < rows.end; ++y) {
      float* row = d.ptr<float>(y);
      std::copy(row, row + w, f.begin());
      lower_envelope(f.data(), w, row, nearest ? at.data() : nullptr, scratch);
      if (nearest) {
        const int32_t* column_row = row_of.ptr<int32_t>(y);
        cv::Point* out = nearest->ptr<cv::Point>(y);
        for (int x = 0; x < w; ++x) {
          const int xs = at[size_t(x)];
          out[x] = xs < 0 ? cv::Point(-1, -1) : cv::Point(xs, column_row[xs]);
        }
      }
    }
    if (rows_done) rows_done(rows);
  }, 16);
  return d;
}

}  // namespace ssdo
