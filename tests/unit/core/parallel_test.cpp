// The kernels' one parallel helper (core/parallel.h): every row once, in strips that do
// not depend on the thread count.
#include "core/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

// The strips parallel_rows hands out, sorted by their first row.
std::vector<cv::Range> strips_of(const cv::Range& rows, int nthreads, int rows_per_strip) {
  std::mutex lock;
  std::vector<cv::Range> strips;
  parallel_rows(rows, nthreads, [&](const cv::Range& r) {
    const std::lock_guard<std::mutex> hold(lock);
    strips.push_back(r);
  }, rows_per_strip);
  std::sort(strips.begin(), strips.end(), [](const cv::Range& a, const cv::Range& b) { return a.start < b.start; });
  return strips;
}

TEST(ParallelRows, EveryRowOnceInStripsIndependentOfTheThreadCount) {
  for (const cv::Range rows : {cv::Range(0, 540), cv::Range(7, 100), cv::Range(3, 4), cv::Range(0, 33)})
    for (int per_strip : {1, 4, 32}) {
      const std::vector<cv::Range> two = strips_of(rows, 2, per_strip);
      ASSERT_FALSE(two.empty());
      // Contiguous, covering [start, end) exactly.
      EXPECT_EQ(two.front().start, rows.start);
      EXPECT_EQ(two.back().end, rows.end);
      for (size_t i = 1; i < two.size(); ++i) EXPECT_EQ(two[i].start, two[i - 1].end);
      // Full strips, then the rest (at most two strips' rows and less than three) in
      // quarter strips, the last one possibly shorter.
      const int n_rows = rows.end - rows.start;
      const int head_end = rows.start + (n_rows - std::min(n_rows, 2 * per_strip)) / per_strip * per_strip;
      const int quarter = std::max(1, per_strip / 4);
      for (const cv::Range& s : two) {
        if (s.start < head_end) EXPECT_EQ(s.size(), per_strip) << s.start;
        else if (s.end < rows.end) EXPECT_EQ(s.size(), quarter) << s.start;
        else EXPECT_LE(s.size(), quarter) << s.start;
      }
      EXPECT_LT(rows.end - head_end, 3 * per_strip);
      // The same strips with one thread of the pool or three.
      for (int threads : {0, 3}) {
        const std::vector<cv::Range> other = strips_of(rows, threads, per_strip);
        ASSERT_EQ(other.size(), two.size()) << threads;
        for (size_t i = 0; i < two.size(); ++i) EXPECT_EQ(other[i], two[i]);
      }
      // Serially: one call over the whole range.
      const std::vector<cv::Range> one = strips_of(rows, 1, per_strip);
      ASSERT_EQ(one.size(), 1u);
      EXPECT_EQ(one[0], rows);
    }
}

// The pool's size is the process's (set_thread_budget), never changed by a call; a call
// with N threads has at most N strips in flight.
TEST(ParallelRows, LeavesThePoolSizeAndKeepsToItsThreads) {
  const int before = cv::getNumThreads();
  set_thread_budget(4);
  ASSERT_EQ(cv::getNumThreads(), 4);
  set_thread_budget(0);  // 0 leaves it as it is
  EXPECT_EQ(cv::getNumThreads(), 4);
  for (int threads : {2, 0}) {
    std::atomic<int> running{0}, most{0};
    parallel_rows(cv::Range(0, 64), threads, [&](const cv::Range&) {
      const int now = ++running;
      for (int m = most.load(); now > m && !most.compare_exchange_weak(m, now);) {}
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      --running;
    }, 1);
    EXPECT_EQ(cv::getNumThreads(), 4) << threads;
    EXPECT_LE(most.load(), threads == 0 ? 4 : threads) << threads;
  }
  set_thread_budget(before);
}

}  // namespace
}  // namespace ssdo
