#include "core/parallel.h"

#include <algorithm>
#include <atomic>

// ThreadSanitizer builds (CMakePresets.json "tsan"): OpenCV's parallel_for_ backend here
// is TBB, an uninstrumented system library whose internal synchronisation TSan cannot
// see. The annotations state exactly the ordering parallel_for_ guarantees (everything
// before the call happens before each strip; each strip happens before the return), so
// races between strips, i.e. in the kernels, are still reported.
#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define SSDO_TSAN_ANNOTATE 1
extern "C" void __tsan_acquire(void* addr);
extern "C" void __tsan_release(void* addr);
#endif
#endif

namespace ssdo {

namespace {

#ifdef SSDO_TSAN_ANNOTATE
// Process-wide sync addresses (TSan keeps their clocks for the whole run; a stack
// address's may be reset when its frame is reused).
char tsan_before, tsan_after;

// A loop body whose first instrumented action is the acquire: OpenCV's std::function
// wrapper would read its (stack) storage before any annotation could run.
class AnnotatedBody : public cv::ParallelLoopBody {
 public:
  explicit AnnotatedBody(const std::function<void(const cv::Range&)>& body) : body_(body) {}
  void operator()(const cv::Range& r) const override {
    __tsan_acquire(&tsan_before);
    body_(r);
    __tsan_release(&tsan_after);
  }

 private:
  const std::function<void(const cv::Range&)>& body_;
};
#endif

void run_parallel_for(const cv::Range& rows, const std::function<void(const cv::Range&)>& body, double nstripes) {
#ifdef SSDO_TSAN_ANNOTATE
  const AnnotatedBody annotated(body);
  __tsan_release(&tsan_before);
  cv::parallel_for_(rows, annotated, nstripes);
  __tsan_acquire(&tsan_after);
#else
  cv::parallel_for_(rows, body, nstripes);
#endif
}

// How many of the pool's threads a call with nthreads != 1 over `tasks` strips or blocks
// uses: the pool as configured, capped by nthreads > 1 and by the tasks, at least 1.
int threads_used(int nthreads, int tasks) {
  const int pool = nthreads > 1 ? std::min(nthreads, cv::getNumThreads()) : cv::getNumThreads();
  return std::max(1, std::min(pool, tasks));
}

}  // namespace

void set_thread_budget(int threads) {
  if (threads > 0) cv::setNumThreads(threads);
}

cv::Rect resolve_roi(const cv::Rect& roi, cv::Size image) {
  if (roi.width <= 0 || roi.height <= 0) return {0, 0, image.width, image.height};
  return roi & cv::Rect(0, 0, image.width, image.height);
}

void parallel_rows(const cv::Range& rows, int nthreads,
                   const std::function<void(const cv::Range&)>& body, int rows_per_strip) {
  if (rows.end <= rows.start) return;
  if (nthreads == 1) {
    body(rows);
    return;
  }
  // Strips of a few rows balance well when cost varies across the image (background
  // rows are cheap). The last two strips' rows go in quarter strips: the threads take the
  // strips in order, so they finish within a quarter strip of each other instead of a
  // whole one (on the 540 rows of a 1080p half grid in 32-row strips, a thread otherwise
  // waits up to one strip: ~5% of the kernel). The split is independent of the thread
  // count, and the kernels' results of the split.
  const int per_strip = std::max(1, rows_per_strip);
  const int tail_strip = std::max(1, per_strip / 4);
  const int n_rows = rows.end - rows.start;
  const int tail_rows = std::min(n_rows, 2 * per_strip);
  const int head_strips = (n_rows - tail_rows) / per_strip;
  const int head_rows = head_strips * per_strip;
  const int n_strips = head_strips + (n_rows - head_rows + tail_strip - 1) / tail_strip;
  auto strip = [&](int i) {
    if (i < head_strips) return cv::Range(rows.start + i * per_strip, rows.start + (i + 1) * per_strip);
    const int begin = rows.start + head_rows + (i - head_strips) * tail_strip;
    return cv::Range(begin, std::min(begin + tail_strip, rows.end));
  };
  const int workers = threads_used(nthreads, n_strips);
  std::atomic<int> next{0};
  // One task per worker, each taking strips until none is left: at most `workers` threads
  // of the pool run this call.
  const std::function<void(const cv::Range&)> take_strips = [&](const cv::Range&) {
    for (int i = next.fetch_add(1); i < n_strips; i = next.fetch_add(1)) body(strip(i));
  };
  run_parallel_for(cv::Range(0, workers), take_strips, workers);
}

void parallel_row_blocks(const cv::Range& rows, int nthreads,
                         const std::function<void(const cv::Range&)>& body, int granularity) {
  if (rows.end <= rows.start) return;
  if (nthreads == 1) {
    body(rows);
    return;
  }
  const int g = std::max(1, granularity);
  const int workers = threads_used(nthreads, (rows.end - rows.start + g - 1) / g);
  // The block from row s: a function of s alone, so the same blocks whichever thread
  // takes each.
  auto block_end = [&](int s) {
    const int left = rows.end - s;
    return s + std::min(left, std::max(g, left / workers / g * g));
  };
  std::atomic<int> next{rows.start};
  const std::function<void(const cv::Range&)> take_blocks = [&](const cv::Range&) {
    for (int s = next.load(); s < rows.end;) {
      const int e = block_end(s);
      if (!next.compare_exchange_weak(s, e)) continue;  // s now holds the current start
      body(cv::Range(s, e));
      s = next.load();
    }
  };
  run_parallel_for(cv::Range(0, workers), take_blocks, workers);
}

}  // namespace ssdo
