#include "kernels/parallel.h"

#include <algorithm>

namespace ssdo {

cv::Rect resolve_roi(const cv::Rect& roi, cv::Size image) {
  if (roi.width <= 0 || roi.height <= 0) return {0, 0, image.width, image.height};
  return roi & cv::Rect(0, 0, image.width, image.height);
}

void parallel_rows(const cv::Range& rows, int nthreads,
                   const std::function<void(const cv::Range&)>& body) {
  if (rows.end <= rows.start) return;
  if (nthreads == 1) {
    body(rows);
    return;
  }
  // Strips of a few rows balance well when cost varies across the image (background
  // rows are cheap); the count is independent of the thread count, so is the output.
  constexpr int kRowsPerStrip = 4;
  const int n_rows = rows.end - rows.start;
  const double nstripes = std::max(1, (n_rows + kRowsPerStrip - 1) / kRowsPerStrip);
  if (nthreads > 1) {
    const int previous = cv::getNumThreads();
    if (previous > nthreads) {
      cv::setNumThreads(nthreads);
      cv::parallel_for_(rows, body, nstripes);
      cv::setNumThreads(previous);
      return;
    }
  }
  cv::parallel_for_(rows, body, nstripes);
}

}  // namespace ssdo
