#include "service/confined_open.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

namespace fs = std::filesystem;

struct Tree {
  fs::path root = fs::temp_directory_path() / ("confined-" + std::to_string(::getpid()));
  Tree() {
    fs::remove_all(root);
    fs::create_directories(root / "in" / "sub");
    fs::create_directories(root / "out");
    std::ofstream(root / "in" / "sub" / "a.txt") << "inside";
    std::ofstream(root / "out" / "b.txt") << "outside";
  }
  ~Tree() { fs::remove_all(root); }
  std::string in() const { return (root / "in").string(); }
};

std::string read_fd(int fd) {
  char buf[64] = {};
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  return n > 0 ? std::string(buf, size_t(n)) : std::string();
}

// Each way of opening beneath a root: the kernel's openat2, and the walk of older kernels.
using OpenFn = int (*)(int, const std::string&, int);
class OpenBeneath : public testing::TestWithParam<OpenFn> {};

TEST_P(OpenBeneath, OpensPlainPathsAndRefusesEverySymlinkAndEscape) {
  Tree t;
  const UniqueFd root(::open(t.in().c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC));
  UniqueFd fd(GetParam()(root.get(), "sub/a.txt", O_RDONLY));
  ASSERT_TRUE(fd);
  EXPECT_EQ(read_fd(fd.get()), "inside");
  EXPECT_LT(GetParam()(root.get(), "../out/b.txt", O_RDONLY), 0);
  // A component swapped for a link out of the root after any check: the open refuses it.
  fs::rename(t.root / "in" / "sub", t.root / "in" / "old");
  fs::create_directory_symlink(t.root / "out", t.root / "in" / "sub");
  std::ofstream(t.root / "out" / "a.txt") << "outside";
  EXPECT_LT(GetParam()(root.get(), "sub/a.txt", O_RDONLY), 0);
  // The last component a link, even to a file inside the root.
  fs::create_symlink(t.root / "in" / "old" / "a.txt", t.root / "in" / "link.txt");
  EXPECT_LT(GetParam()(root.get(), "link.txt", O_RDONLY), 0);
}

INSTANTIATE_TEST_SUITE_P(Both, OpenBeneath, testing::Values(&open_beneath, &open_beneath_walk));

TEST(ConfinedOpen, TheOpenedFileIsTheCheckedOneOrNone) {
  Tree t;
  UniqueFd fd;
  std::string canonical, error;
  ASSERT_TRUE(open_confined_file((t.root / "in/sub/a.txt").string(), {t.in()}, fd, canonical, error)) << error;
  // Swapped after the open: the descriptor still reads the checked file, also by its name.
  fs::remove(t.root / "in/sub/a.txt");
  fs::create_symlink(t.root / "out/b.txt", t.root / "in/sub/a.txt");
  EXPECT_EQ(read_fd(fd.get()), "inside");
  std::ifstream by_name(fd_path(fd.get()));
  std::string text;
  std::getline(by_name, text);
  EXPECT_EQ(text, "inside");
  // Opened now: the link's target is outside the root.
  EXPECT_FALSE(open_confined_file((t.root / "in/sub/a.txt").string(), {t.in()}, fd, canonical, error));
  EXPECT_NE(error.find("outside the allowed folders"), std::string::npos) << error;
  // A FIFO is refused without blocking.
  ASSERT_EQ(::mkfifo((t.root / "in/fifo").c_str(), 0600), 0);
  EXPECT_FALSE(open_confined_file((t.root / "in/fifo").string(), {t.in()}, fd, canonical, error));
  EXPECT_NE(error.find("not a regular file"), std::string::npos) << error;
  EXPECT_FALSE(open_confined_file((t.root / "in/fifo").string(), {}, fd, canonical, error));
}

}  // namespace
}  // namespace ssdo
