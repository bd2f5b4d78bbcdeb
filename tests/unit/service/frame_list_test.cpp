#include "service/frame_list.h"

#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("ssdo_frames_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  void touch(const std::string& name) const { std::ofstream(path / name) << "x"; }
};

TEST(FrameList, FolderGivesSortedExrFramesWithoutOutputsOrHiddenFiles) {
  TempDir d;
  for (const char* n : {"b.exr", "a.exr", "c.EXR", "a.ssdo.exr", ".tmp.exr", "notes.txt"}) d.touch(n);
  std::vector<std::string> frames;
  std::string error;
  ASSERT_TRUE(expand_inputs({d.path.string()}, frames, error)) << error;
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(fs::path(frames[0]).filename(), "a.exr");
  EXPECT_EQ(fs::path(frames[1]).filename(), "b.exr");
  EXPECT_EQ(fs::path(frames[2]).filename(), "c.EXR");
}

TEST(FrameList, MissingInputIsNamed) {
  std::vector<std::string> frames;
  std::string error;
  EXPECT_FALSE(expand_inputs({"/nonexistent/frame.exr"}, frames, error));
  EXPECT_NE(error.find("/nonexistent/frame.exr"), std::string::npos);
}

TEST(FrameList, OutputPathReplacesExtension) {
  EXPECT_EQ(output_path_for("/a/b/shot_0001.exr", "/out"), "/out/shot_0001.ssdo.exr");
  EXPECT_EQ(output_path_for("frame.EXR", "o"), "o/frame.ssdo.exr");
}

TEST(FrameList, UpToDateComparesModificationTimes) {
  TempDir d;
  d.touch("in.exr");
  const std::string in = (d.path / "in.exr").string(), out = (d.path / "out.exr").string();
  EXPECT_FALSE(output_up_to_date(in, out));  // no output yet
  d.touch("out.exr");
  fs::last_write_time(out, fs::last_write_time(in) + std::chrono::seconds(1));
  EXPECT_TRUE(output_up_to_date(in, out));
  fs::last_write_time(in, fs::last_write_time(out) + std::chrono::seconds(1));
  EXPECT_FALSE(output_up_to_date(in, out));
}

}  // namespace
}  // namespace ssdo

#include "formats/output_writer.h"

namespace ssdo {
namespace {

TEST(FrameList, OnlyThisHostsAbandonedTempFilesAreRemoved) {
  TempDir d;
  const std::string host = temp_file_host();
  const std::string dead = "." "a.ssdo.exr.tmp-" + host + "-999999999-1f";   // no such pid
  const std::string live = ".b.ssdo.exr.tmp-" + host + "-" + std::to_string(::getpid()) + "-2e";
  const std::string other = ".c.ssdo.exr.tmp-farm-node-17-999999999-3d";      // another host
  const std::string preview = ".d.ssdo.ao.png.tmp-" + host + "-999999998-4c";  // no such pid
  const std::string foreign = ".notes.tmp-" + host + "-999999997-5b";           // not ssdo's
  // A long output's temp file keeps the end of its name (formats/output_writer.cpp).
  const std::string long_dead = ".~" + std::string(180, 'n') + ".ssdo.exr.tmp-" + host + "-999999996-6a";
  // The same host name in another PID namespace (a container) or boot: its pids are not ours.
  std::string elsewhere = host;
  elsewhere.back() = elsewhere.back() == '0' ? '1' : '0';
  const std::string other_space = ".e.ssdo.exr.tmp-" + elsewhere + "-999999995-7f";
  for (const std::string& n : {dead, live, other, preview, foreign, long_dead, other_space}) d.touch(n);
  EXPECT_EQ(remove_stale_temp_files(d.path.string()), 3);
  EXPECT_TRUE(fs::exists(d.path / other_space));
  EXPECT_FALSE(fs::exists(d.path / long_dead));
  EXPECT_FALSE(fs::exists(d.path / dead));
  EXPECT_FALSE(fs::exists(d.path / preview));
  EXPECT_TRUE(fs::exists(d.path / live));
  EXPECT_TRUE(fs::exists(d.path / other));
  EXPECT_TRUE(fs::exists(d.path / foreign));
}

// What a worker that died while writing left: its own temp files only, whatever the others.
TEST(FrameList, ADeadWorkersTempFilesAreRemoved) {
  TempDir d;
  const std::string host = temp_file_host();
  const std::string its = ".a.ssdo.exr.tmp-" + host + "-4242-1f", its_preview = ".a.ssdo.ao.png.tmp-" + host + "-4242-2e";
  const std::string other_pid = ".b.ssdo.exr.tmp-" + host + "-4243-3d", other_host = ".c.ssdo.exr.tmp-farm-node-4242-4c";
  for (const std::string& n : {its, its_preview, other_pid, other_host}) d.touch(n);
  EXPECT_EQ(remove_temp_files_of(d.path.string(), 4242), 2);
  EXPECT_FALSE(fs::exists(d.path / its));
  EXPECT_FALSE(fs::exists(d.path / its_preview));
  EXPECT_TRUE(fs::exists(d.path / other_pid));
  EXPECT_TRUE(fs::exists(d.path / other_host));
}

}  // namespace
}  // namespace ssdo
