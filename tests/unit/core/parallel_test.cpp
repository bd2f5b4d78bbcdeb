// The kernels' one parallel helper (core/parallel.h): every row once, in strips that do
// not depend on the thread count, or in guided blocks that shrink towards the end.
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

// The row ranges a helper hands out (split(body) calls it with the body), sorted by their
// first row.
template <class Split>
std::vector<cv::Range> ranges_of(const Split& split) {
  std::mutex lock;
  std::vector<cv::Range> ranges;
  split([&](const cv::Range& r) {
    const std::lock_guard<std::mutex> hold(lock);
    ranges.push_back(r);
  });
  std::sort(ranges.begin(), ranges.end(), [](const cv::Range& a, const cv::Range& b) { return a.start < b.start; });
  return ranges;
}

// The strips parallel_rows hands out, sorted by their first row.
std::vector<cv::Range> strips_of(const cv::Range& rows, int nthreads, int rows_per_strip) {
  return ranges_of([&](const auto& body) { parallel_rows(rows, nthreads, body, rows_per_strip); });
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

// The blocks parallel_row_blocks hands out, sorted by their first row.
std::vector<cv::Range> blocks_of(const cv::Range& rows, int nthreads, int granularity) {
  return ranges_of([&](const auto& body) { parallel_row_blocks(rows, nthreads, body, granularity); });
}

// Guided self-scheduling: every row once, each block (rows left) / threads rows rounded down
// to the granularity and at least that, so the blocks shrink; the same blocks on every
// call with the same thread count, and one block serially.
TEST(ParallelRowBlocks, EveryRowOnceInBlocksThatShrinkTowardsTheEnd) {
  const int before = cv::getNumThreads();
  set_thread_budget(4);
  for (const cv::Range rows : {cv::Range(0, 1080), cv::Range(7, 100), cv::Range(3, 4), cv::Range(0, 540)})
    for (int granularity : {1, 16})
      for (int threads : {2, 3}) {
        const std::vector<cv::Range> blocks = blocks_of(rows, threads, granularity);
        ASSERT_FALSE(blocks.empty());
        EXPECT_EQ(blocks.front().start, rows.start);
        EXPECT_EQ(blocks.back().end, rows.end);
        for (size_t i = 0; i < blocks.size(); ++i) {
          const cv::Range& b = blocks[i];
          if (i > 0) {
            EXPECT_EQ(b.start, blocks[i - 1].end);
          }
          const int left = rows.end - b.start;
          const int expected = std::min(left, std::max(granularity, left / threads / granularity * granularity));
          EXPECT_EQ(b.size(), expected) << threads << " threads, block at " << b.start;
        }
        const std::vector<cv::Range> again = blocks_of(rows, threads, granularity);
        ASSERT_EQ(again.size(), blocks.size());
        for (size_t i = 0; i < blocks.size(); ++i) EXPECT_EQ(again[i], blocks[i]);
        const std::vector<cv::Range> one = blocks_of(rows, 1, granularity);
        ASSERT_EQ(one.size(), 1u);
        EXPECT_EQ(one[0], rows);
      }
  // 1080 rows on two threads in blocks of 16: 528, 272, 128, 64, 32, 16, 16, 16, 8.
  const std::vector<cv::Range> frame = blocks_of(cv::Range(0, 1080), 2, 16);
  std::vector<int> sizes;
  for (const cv::Range& b : frame) sizes.push_back(b.size());
  EXPECT_EQ(sizes, (std::vector<int>{528, 272, 128, 64, 32, 16, 16, 16, 8}));
  set_thread_budget(before);
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
