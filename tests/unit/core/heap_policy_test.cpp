#include "core/heap_policy.h"
#include "core/sanitizer_build.h"

#include <malloc.h>

#include <cstdlib>
#include <cstring>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

// A frame-sized block comes from the heap, not from mmap; freed, it stays mapped for the
// next frame; return_free_memory() hands it back.
TEST(HeapPolicy, FreedFramesStayInTheHeapUntilReturned) {
#ifdef SSDO_SANITIZER_BUILD
  GTEST_SKIP() << "the sanitizer's allocator replaces malloc's heap";
#endif
  keep_freed_memory_for_reuse();
  constexpr size_t kBlockBytes = size_t(48) << 20;  // above malloc's largest mmap threshold (32 MiB)
  const struct mallinfo2 before = mallinfo2();
  void* block = std::malloc(kBlockBytes);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, kBlockBytes);
  const struct mallinfo2 held = mallinfo2();
  EXPECT_EQ(held.hblkhd, before.hblkhd) << "the block was mapped with mmap";
  // In the heap's bytes in use (the heap may have had room for it already: earlier tests in
  // the same program leave free blocks behind).
  EXPECT_GE(held.uordblks, before.uordblks + kBlockBytes);
  std::free(block);
  const struct mallinfo2 freed = mallinfo2();
  EXPECT_EQ(freed.arena, held.arena) << "the heap was trimmed on free";
  EXPECT_GE(freed.fordblks, kBlockBytes);
  EXPECT_TRUE(return_free_memory()) << "the free block was not returned";
}

}  // namespace
}  // namespace ssdo
