#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "service/path_policy.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

struct Tree {
  fs::path root;
  Tree() {
    root = fs::temp_directory_path() / ("ssdo_paths_" + std::to_string(::getpid()));
    fs::remove_all(root);
    fs::create_directories(root / "allowed" / "sub");
    fs::create_directories(root / "allowed2");
    fs::create_directories(root / "outside");
    fs::create_directories(root / "out");
    std::ofstream(root / "allowed" / "sub" / "a.exr") << "x";
    std::ofstream(root / "allowed2" / "b.exr") << "x";
    std::ofstream(root / "outside" / "secret.exr") << "x";
    fs::create_symlink(root / "outside" / "secret.exr", root / "allowed" / "escape.exr");
    fs::create_symlink(root / "allowed" / "sub" / "a.exr", root / "allowed" / "inside.exr");
    fs::create_symlink(root / "outside", root / "out" / "linkdir");
  }
  ~Tree() { fs::remove_all(root); }
  std::string operator()(const std::string& rel) const { return (root / rel).string(); }
};

TEST(PathIsUnder, ComponentWise) {
  EXPECT_TRUE(path_is_under("/data/in", "/data/in"));
  EXPECT_TRUE(path_is_under("/data/in/a.exr", "/data/in"));
  EXPECT_FALSE(path_is_under("/data/input2/a.exr", "/data/in"));
  EXPECT_FALSE(path_is_under("/data", "/data/in"));
  EXPECT_TRUE(path_is_under("/anything", "/"));
  EXPECT_FALSE(path_is_under("/data/in", ""));
}

TEST(AllowedInput, InsideRootsOnlyAfterSymlinksAndDotDot) {
  Tree t;
  const std::vector<std::string> roots = {t("allowed"), t("allowed2")};
  std::string resolved, error;
  EXPECT_TRUE(resolve_allowed_input(t("allowed/sub/a.exr"), roots, resolved, error)) << error;
  EXPECT_EQ(resolved, t("allowed/sub/a.exr"));
  EXPECT_TRUE(resolve_allowed_input(t("allowed2/b.exr"), roots, resolved, error)) << error;
  EXPECT_TRUE(resolve_allowed_input(t("allowed/inside.exr"), roots, resolved, error)) << error;
  EXPECT_EQ(resolved, t("allowed/sub/a.exr"));

  EXPECT_FALSE(resolve_allowed_input(t("allowed/../outside/secret.exr"), roots, resolved, error));
  EXPECT_NE(error.find("outside the allowed"), std::string::npos) << error;
  EXPECT_FALSE(resolve_allowed_input(t("allowed/sub/../../outside/secret.exr"), roots, resolved, error));
  EXPECT_FALSE(resolve_allowed_input(t("allowed/escape.exr"), roots, resolved, error));
  EXPECT_NE(error.find(t("outside/secret.exr")), std::string::npos) << error;
  EXPECT_FALSE(resolve_allowed_input(t("allowed/missing.exr"), roots, resolved, error));
  EXPECT_NE(error.find("no such"), std::string::npos) << error;
  EXPECT_FALSE(resolve_allowed_input(t("allowed/sub/a.exr"), {}, resolved, error));
}

TEST(AllowedOutput, FolderMustResolveUnderTheOutputRoot) {
  Tree t;
  const std::string out = t("out");
  std::string resolved, error;
  EXPECT_TRUE(resolve_allowed_output(t("out/x.ssdo.exr"), out, resolved, error)) << error;
  EXPECT_EQ(resolved, t("out/x.ssdo.exr"));
  EXPECT_FALSE(resolve_allowed_output(t("out/../x.ssdo.exr"), out, resolved, error));
  EXPECT_FALSE(resolve_allowed_output(t("out/linkdir/x.ssdo.exr"), out, resolved, error));
  EXPECT_FALSE(resolve_allowed_output(t("out/nofolder/x.ssdo.exr"), out, resolved, error));
  EXPECT_FALSE(resolve_allowed_output(t("out/.."), out, resolved, error));
  fs::create_symlink(t("outside/secret.exr"), t("out/trap.ssdo.exr"));
  EXPECT_FALSE(resolve_allowed_output(t("out/trap.ssdo.exr"), out, resolved, error));
  EXPECT_NE(error.find("symbolic link"), std::string::npos) << error;
}

}  // namespace
}  // namespace ssdo
