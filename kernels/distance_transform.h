// Squared Euclidean distance transforms of sampled functions: the lower envelope of the
// parabolas rooted at the samples (Felzenszwalb & Huttenlocher 2012, "Distance Transforms of
// Sampled Functions", algorithm DT(f)), along one line; separable over an image (a pass
// along its columns, then one along its rows over the columns' results: squared_distance_
// to_marks, whose column pass over binary marks is two sweeps along each column). The
// temporal filter's distances to its marks and the thickness estimate's nearest silhouette
// take it.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include <opencv2/core.hpp>

namespace ssdo {

// Scratch of lower_envelope for lines of up to n samples.
struct EnvelopeScratch {
  std::vector<int> v;
  std::vector<double> z;
  explicit EnvelopeScratch(int n) : v(std::size_t(n)), z(std::size_t(n) + 1) {}
};

// d[q] = min over p with finite f[p] of f[p] + (q - p)^2, q in [0, n) (+inf when no f[p] is
// finite); `nearest` (may be null) receives the p attaining it (-1 when none).
void lower_envelope(const float* f, int n, float* d, int* nearest, EnvelopeScratch& scratch);

// Squared Euclidean distance, in pixels, from each pixel to the nearest nonzero pixel of
// `marks` (CV_8UC1); CV_32FC1, +inf everywhere when there is no mark. With `nearest`, that
// mark's position too (CV_32SC2, (-1, -1) when there is none). A pass along the columns,
// then one along the rows over their results; the same bits for any nthreads. rows_done,
// when given, is called with each strip of rows as soon as their distances and nearest marks
// are written, on the thread that wrote them, each row in one call: a caller's pass over the
// rows runs within the transform's last instead of after it (one pass over the threads
// fewer), with its scratch taken once per strip.
cv::Mat squared_distance_to_marks(const cv::Mat& marks, int nthreads = 0, cv::Mat* nearest = nullptr,
                                  const std::function<void(const cv::Range&)>& rows_done = {});

}  // namespace ssdo
