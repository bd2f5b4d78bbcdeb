#include "service/frame_range.h"

#include <numeric>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

std::vector<int> ranges(const std::string& spec) {
  std::vector<int> f;
  std::string error;
  EXPECT_TRUE(parse_frame_ranges(spec, f, error)) << spec << ": " << error;
  return f;
}

TEST(FrameRange, OiiotoolSyntax) {
  EXPECT_EQ(ranges("1-5"), (std::vector<int>{1, 2, 3, 4, 5}));
  EXPECT_EQ(ranges("1-10x3,20"), (std::vector<int>{1, 4, 7, 10, 20}));
  EXPECT_EQ(ranges("7"), (std::vector<int>{7}));
  EXPECT_EQ(ranges("5-3"), (std::vector<int>{5, 4, 3}));
  EXPECT_EQ(ranges("-2-1"), (std::vector<int>{-2, -1, 0, 1}));
  EXPECT_EQ(ranges("1-100x2,200").size(), 51u);
}

TEST(FrameRange, ErrorsNameTheItem) {
  std::vector<int> f;
  std::string error;
  for (const char* bad : {"", "1-", "a-b", "1-10x0", "1-10x-2", "1,,2", "1-2-3", "1x"}) {
    f.clear();
    EXPECT_FALSE(parse_frame_ranges(bad, f, error)) << bad;
    EXPECT_FALSE(error.empty());
  }
  EXPECT_FALSE(parse_frame_ranges("1-2000000000", f, error));
  EXPECT_NE(error.find("more than"), std::string::npos);
}

TEST(FramePattern, HashAtAndPrintf) {
  EXPECT_EQ(expand_frame_pattern("/r/shot.####.exr", 42), "/r/shot.0042.exr");
  EXPECT_EQ(expand_frame_pattern("shot.#.exr", 7), "shot.0007.exr");  // lone '#' = 4 digits
  EXPECT_EQ(expand_frame_pattern("shot.@@@.exr", 7), "shot.007.exr");
  EXPECT_EQ(expand_frame_pattern("shot.%04d.exr", 12345), "shot.12345.exr");
  EXPECT_EQ(expand_frame_pattern("shot.%d.exr", 3), "shot.3.exr");
  EXPECT_EQ(expand_frame_pattern("/dir#1/shot.exr", 3), "/dir#1/shot.exr");  // folders untouched
  EXPECT_TRUE(has_frame_pattern("a.%03d.exr"));
  EXPECT_FALSE(has_frame_pattern("a.exr"));
  EXPECT_FALSE(has_frame_pattern("100%.exr"));
}

TEST(Chunk, SlicesCoverWithoutOverlap) {
  std::vector<int> items(10);
  std::iota(items.begin(), items.end(), 1);
  std::vector<int> all;
  for (int i = 1; i <= 4; ++i) {
    const auto s = chunk_slice(items, i, 4);
    EXPECT_GE(s.size(), 2u);
    EXPECT_LE(s.size(), 3u);
    all.insert(all.end(), s.begin(), s.end());
  }
  EXPECT_EQ(all, items);
  EXPECT_EQ(chunk_slice(items, 3, 3), (std::vector<int>{7, 8, 9, 10}));
  EXPECT_TRUE(chunk_slice(std::vector<int>{1}, 1, 2).empty());  // more chunks than frames
}

TEST(Chunk, ParseValidatesRange) {
  int i = 0, n = 0;
  std::string error;
  ASSERT_TRUE(parse_chunk("2/8", i, n, error));
  EXPECT_EQ(i, 2);
  EXPECT_EQ(n, 8);
  EXPECT_FALSE(parse_chunk("0/8", i, n, error));
  EXPECT_NE(error.find("count from 1"), std::string::npos);
  EXPECT_FALSE(parse_chunk("9/8", i, n, error));
  EXPECT_FALSE(parse_chunk("3", i, n, error));
  EXPECT_FALSE(parse_chunk("a/b", i, n, error));
  EXPECT_FALSE(parse_chunk("1/0", i, n, error));
  EXPECT_EQ(error, "--chunk '1/0': N, the number of chunks, must be at least 1");
}

}  // namespace
}  // namespace ssdo
