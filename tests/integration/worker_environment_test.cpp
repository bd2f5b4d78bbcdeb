// The environment a worker process starts with: the parent's, the C library's tunables
// included (a user's choice of the heap's pages, core/heap_policy.h).
#include <algorithm>
#include <chrono>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "run_binary.h"
#include "service/worker_process.h"

namespace ssdo::test {
namespace {

constexpr const char* kMarker = "SSDO_WORKER_ENV_MARKER=kept";

// The NAME=VALUE entries of process pid's environment, once it holds kMarker (set only in
// this process after it started, so seen only in the worker's own image: right after
// posix_spawn returns, /proc may still show the environment of the image before exec).
std::vector<std::string> environment_of(pid_t pid) {
  std::vector<std::string> entries;
  for (int attempt = 0; attempt < 500; ++attempt) {
    std::ifstream in("/proc/" + std::to_string(pid) + "/environ", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    entries.clear();
    for (size_t at = 0; at < bytes.size();) {
      const size_t end = std::min(bytes.find('\0', at), bytes.size());
      entries.push_back(bytes.substr(at, end - at));
      at = end + 1;
    }
    if (std::find(entries.begin(), entries.end(), kMarker) != entries.end()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return entries;
}

std::vector<std::string> tunables_of(const std::vector<std::string>& environment) {
  std::vector<std::string> found;
  for (const std::string& e : environment)
    if (e.starts_with("GLIBC_TUNABLES=")) found.push_back(e);
  return found;
}

// A worker's environment is its parent's: nothing added (no tunables when the parent has
// none) and the parent's tunables kept.
TEST(WorkerEnvironment, TheParentsEnvironment) {
  const ScopedVariable marker("SSDO_WORKER_ENV_MARKER", "kept");  // kMarker
  {
    const ScopedVariable unset("GLIBC_TUNABLES", std::nullopt);
    WorkerProcess worker(WorkerLimits{}, SSDO_BINARY);
    std::string error;
    ASSERT_TRUE(worker.start(error)) << error;
    const std::vector<std::string> env = environment_of(worker.pid());
    EXPECT_NE(std::find(env.begin(), env.end(), kMarker), env.end());
    EXPECT_TRUE(tunables_of(env).empty());
  }
  {
    const ScopedVariable chosen("GLIBC_TUNABLES", "glibc.malloc.check=0:glibc.malloc.hugetlb=1");
    WorkerProcess worker(WorkerLimits{}, SSDO_BINARY);
    std::string error;
    ASSERT_TRUE(worker.start(error)) << error;
    // /proc shows the tunables as the worker's C library rewrote them in place (glibc 2.36
    // cuts glibc.malloc.hugetlb after another tunable there, while the process itself sees
    // and applies the whole string).
    const std::vector<std::string> env = environment_of(worker.pid());
    const std::vector<std::string> tunables = tunables_of(env);
    ASSERT_EQ(tunables.size(), 1u);
    EXPECT_TRUE(tunables[0].starts_with("GLIBC_TUNABLES=glibc.malloc.check=0")) << tunables[0];
    EXPECT_NE(std::find(env.begin(), env.end(), kMarker), env.end());
  }
}

}  // namespace
}  // namespace ssdo::test
