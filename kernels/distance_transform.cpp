#include "kernels/distance_transform.h"

#include <algorithm>
#include <limits>

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

cv::Mat squared_distance_to_marks(const cv::Mat& marks, int nthreads, cv::Mat* nearest,
                                  const std::function<void(int)>& row_done) {
  CV_Assert(marks.type() == CV_8UC1);
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const int w = marks.cols, h = marks.rows;
  cv::Mat d(marks.size(), CV_32FC1), row_of;
  if (nearest) row_of.create(marks.size(), CV_32SC1);
  // Columns first (0 on a mark, +inf elsewhere), then rows over the columns' results: the
  // squared Euclidean distance is separable, and the nearest mark of a row's pass lies in the
  // column its nearest sample names, at the row that column's pass found.
  parallel_rows(cv::Range(0, w), nthreads, [&](const cv::Range& cols) {
    const size_t n = static_cast<size_t>(h);
    std::vector<float> f(n), out(n);
    std::vector<int> at(n);
    EnvelopeScratch scratch(h);
    for (int x = cols.start; x < cols.end; ++x) {
      for (int y = 0; y < h; ++y) f[size_t(y)] = marks.at<uint8_t>(y, x) ? 0.0f : kInf;
      lower_envelope(f.data(), h, out.data(), nearest ? at.data() : nullptr, scratch);
      for (int y = 0; y < h; ++y) d.at<float>(y, x) = out[size_t(y)];
      if (nearest)
        for (int y = 0; y < h; ++y) row_of.at<int32_t>(y, x) = at[size_t(y)];
    }
  }, 16);
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
      if (row_done) row_done(y);
    }
  }, 16);
  return d;
}

}  // namespace ssdo
