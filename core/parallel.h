// The one parallel helper of the kernels: splits a row range into strips and runs a
// body over them with cv::parallel_for_. Kernels call it; nothing else in kernels/
// calls cv::parallel_for_ directly.
//
// OpenCV runs a nested or concurrent second parallel_for_ serially (a process-wide
// flag), so the caller decides where parallelism lives: inside a frame (nthreads != 1)
// or across frames (nthreads = 1 per frame). Results never depend on the split.
//
// The pool's size is a property of the process, set once where it starts (a worker, a
// command: set_thread_budget); parallel_rows never changes it.
#pragma once

#include <functional>

#include <opencv2/core.hpp>

namespace ssdo {

// Sizes OpenCV's pool for the whole process: threads > 0 = that many (1 = no pool: every
// parallel_rows runs in its caller), 0 = OpenCV's default (every core). Call once, before
// any parallel_rows, from the thread that starts the work.
void set_thread_budget(int threads);

// Rows of `roi` to process; an empty roi means the whole image of the given size.
cv::Rect resolve_roi(const cv::Rect& roi, cv::Size image);

// Runs body(rows) over strips covering [rows.start, rows.end).
// nthreads: 1 = serially in the calling thread; 0 = the pool as configured
// (set_thread_budget); N > 1 = the pool, with at most N of its threads used for this call
// (at most N strips in flight).
// rows_per_strip: the strip height, >= 1 (independent of the thread count, so the split
// never depends on it); small strips balance uneven rows, tiled kernels ask for their
// tile height so that a tile's halo is read once per tile. The threads take the strips in
// order, and the last two strips' rows come in strips of a quarter of the height, so
// that the threads finish close together.
void parallel_rows(const cv::Range& rows, int nthreads,
                   const std::function<void(const cv::Range&)>& body, int rows_per_strip = 4);

}  // namespace ssdo
