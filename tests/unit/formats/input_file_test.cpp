// The first check of a named input: what would block or feed a reader without end (a FIFO,
// a device) and what is too large are refused by name, before any reader opens them; the
// readers of sidecars, environment maps and frames make that check.
#include "formats/input_file.h"

#include <sys/stat.h>

#include <fstream>

#include <gtest/gtest.h>

#include "formats/camera_io.h"
#include "formats/env_map.h"
#include "formats/gbuffer_reader.h"
#include "tests/unit/formats/formats_test_util.h"

namespace ssdo {
namespace {

using test::ScratchDir;

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(InputFile, ARegularFileWithinTheLimitIsAccepted) {
  ScratchDir dir;
  std::ofstream(dir.path / "a.json") << "{}";
  EXPECT_EQ(input_file_error((dir.path / "a.json").string(), "camera sidecar", 2), "");
  const std::string e = input_file_error((dir.path / "a.json").string(), "camera sidecar", 1);
  EXPECT_TRUE(contains(e, "camera sidecar " + (dir.path / "a.json").string() + ": 2 bytes, more than the 1"))
      << e;
}

TEST(InputFile, MissingFolderFifoAndDeviceAreRefusedByName) {
  ScratchDir dir;
  const std::string fifo = (dir.path / "pipe").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(input_file_error((dir.path / "none").string(), "environment map"),
            "environment map " + (dir.path / "none").string() + ": no such file");
  EXPECT_EQ(input_file_error(dir.path.string(), ""), dir.path.string() + ": a folder, not a file");
  for (const std::string& path : {fifo, std::string("/dev/zero")})
    EXPECT_TRUE(contains(input_file_error(path, "x"), "x " + path + ": not a regular file")) << path;
}

// Each reader refuses a FIFO instead of blocking on it (the test would hang) and
// /dev/zero instead of reading it without end.
TEST(InputFile, ReadersRefuseAFifoAndADevice) {
  ScratchDir dir;
  const std::string fifo = (dir.path / "pipe.exr").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& path : {fifo, std::string("/dev/zero")}) {
    std::string error;
    EXPECT_FALSE(read_camera_sidecar(path, &error).has_value());
    EXPECT_TRUE(contains(error, "camera sidecar " + path + ": not a regular file")) << error;
    EXPECT_TRUE(contains(read_env_map(path).error, "not a regular file")) << path;
    EXPECT_TRUE(contains(check_env_map(path), "not a regular file")) << path;
    EXPECT_TRUE(contains(read_gbuffer(path, ReadOptions{}).error, path + ": not a regular file")) << path;
  }
  // A sidecar is text a person writes: 16 MiB at most.
  const std::string big = (dir.path / "big.camera.json").string();
  std::ofstream(big).close();
  std::filesystem::resize_file(big, kMaxTextFileBytes + 1);
  std::string error;
  EXPECT_FALSE(read_camera_sidecar(big, &error).has_value());
  EXPECT_TRUE(contains(error, "more than the")) << error;
}

}  // namespace
}  // namespace ssdo
