#include "service/batch_progress.h"

#include <gtest/gtest.h>

namespace ssdo {
namespace {

// Two workers whose first frames take 1 s each: when the first ends, the batch has made
// 2 frames/s (its second frame is about to end), not the 1 frame in 1 s measured so far.
TEST(BatchRate, WorkersSideBySideCountFromTheirFirstFrame) {
  EXPECT_DOUBLE_EQ(batch_frames_per_s(1, 1.0, 2, 1000.0), 2.0);
  EXPECT_DOUBLE_EQ(batch_frames_per_s(1, 1.0, 1, 1000.0), 1.0);
}

// Where the measure is higher (frames that failed at once among those computed, a worker's
// start in a first frame's time), it is the rate; before any frame, the measure alone.
TEST(BatchRate, TheMeasureWinsWhenItIsHigherAndBeforeAnyFrame) {
  EXPECT_DOUBLE_EQ(batch_frames_per_s(10, 2.0, 2, 1000.0), 5.0);
  EXPECT_DOUBLE_EQ(batch_frames_per_s(0, 3.0, 2, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(batch_frames_per_s(3, 2.0, 4, 0.0), 1.5);
}

}  // namespace
}  // namespace ssdo
