// The parallel helpers of the kernels: split a row range into strips (or blocks) and run a
// body over them with cv::parallel_for_. Kernels call them; nothing else in kernels/
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

// Runs body(rows) over blocks covering [rows.start, rows.end), for kernels whose first rows
// of a block cost more than the rest (a tiled filter's halo, computed once per block and
// then carried from tile to tile): the blocks are few and large, shrinking towards the end
// so that the threads still finish close together. Guided self-scheduling (Polychronopoulos
// & Kuck 1987, "Guided self-scheduling: a practical scheduling scheme for parallel
// supercomputers"): the block starting at row s holds (rows.end - s) / W rows, W the threads
// used, rounded down to a multiple of `granularity`, and at least `granularity` (the last
// block: what is left). The blocks depend on the thread count (not on which thread takes
// them): only for kernels whose results do not depend on the split. nthreads as for
// parallel_rows; 1 = one block, serially.
void parallel_row_blocks(const cv::Range& rows, int nthreads,
                         const std::function<void(const cv::Range&)>& body, int granularity);

}  // namespace ssdo
