// Runs the real ssdo binary for integration tests and captures its output.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>

#include <gtest/gtest.h>

namespace ssdo::test {

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr interleaved
};

// Sets (or, with nullopt, unsets) a variable of this process, which the processes it
// starts inherit, for a scope.
class ScopedVariable {
 public:
  ScopedVariable(const char* name, std::optional<std::string> value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    value ? ::setenv(name, value->c_str(), 1) : ::unsetenv(name);
  }
  ~ScopedVariable() { old_ ? ::setenv(name_, old_->c_str(), 1) : ::unsetenv(name_); }
  ScopedVariable(const ScopedVariable&) = delete;
  ScopedVariable& operator=(const ScopedVariable&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

// Runs `SSDO_BINARY args` through the shell (args are trusted test strings).
inline RunResult run_ssdo(const std::string& args) {
  RunResult r;
  const std::string cmd = std::string(SSDO_BINARY) + " " + args + " 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

inline std::filesystem::path shared_dir() { return SSDO_SHARED_DIR; }

// A file's bytes; empty when it cannot be read.
inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
inline std::filesystem::path source_dir() { return SSDO_SOURCE_DIR; }

// A fresh empty folder per test, removed afterwards.
struct ScratchDir {
  std::filesystem::path path;
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path = std::filesystem::temp_directory_path() /
           ("ssdo_it_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~ScratchDir() { std::filesystem::remove_all(path); }
  std::string operator/(const std::string& name) const { return (path / name).string(); }
};

#define SSDO_REQUIRE_SHARED()                                                             \
  do {                                                                                    \
    if (!std::filesystem::exists(::ssdo::test::shared_dir() / "gbuffers"))                \
      GTEST_SKIP() << "../shared/gbuffers not found beside the clone: "                  \
                   << ::ssdo::test::shared_dir();                                         \
  } while (0)

}  // namespace ssdo::test
