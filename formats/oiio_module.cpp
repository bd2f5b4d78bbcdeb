#include "formats/oiio_module.h"

#include <dlfcn.h>

#include <atomic>
#include <filesystem>
#include <mutex>
#include <vector>

#include "formats/chart.h"
#include "formats/oiio/module_api.h"

namespace ssdo {
namespace oiio_module {
namespace {

namespace fs = std::filesystem;

constexpr const char* kModuleFile = "libssdo_oiio.so";

std::mutex g_mutex;
const Api* g_api = nullptr;  // set once, under g_mutex
std::string g_error;         // why loading failed (kept: later calls fail the same way)
bool g_tried = false;
std::atomic<int> g_threads{0};

// Where the module may be: beside the running binary (the build tree's and an install's
// layout), then where this build put it (test programs live in other folders).
std::vector<fs::path> candidates() {
  std::vector<fs::path> paths;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    paths.push_back(self.parent_path() / kModuleFile);
    paths.push_back(self.parent_path().parent_path() / "lib" / "ssdo" / kModuleFile);
  }
#ifdef SSDO_OIIO_MODULE_PATH
  paths.emplace_back(SSDO_OIIO_MODULE_PATH);
#endif
  return paths;
}

const Api* api(std::string* error) {
  std::lock_guard lock(g_mutex);
  if (!g_tried) {
    g_tried = true;
    std::string tried;
    for (const fs::path& path : candidates()) {
      std::error_code ec;
      if (!fs::exists(path, ec)) {
        tried += (tried.empty() ? "" : ", ") + path.string();
        continue;
      }
      void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!handle) {
        const char* why = ::dlerror();
        g_error = "cannot load the OpenImageIO module " + path.string() + ": " +
                  (why ? why : "unknown error");
        break;
      }
      using Entry = const Api* (*)();
      auto entry = reinterpret_cast<Entry>(::dlsym(handle, "ssdo_oiio_module_api"));
      const Api* table = entry ? entry() : nullptr;
      if (!table || table->version != kVersion) {
        g_error = "the OpenImageIO module " + path.string() +
                  " does not match this binary (rebuild it with the binary)";
        break;  // the handle stays: unloading a C++ library is not worth its risks
      }
      g_api = table;
      if (const int threads = g_threads.load(); threads > 0) g_api->set_threads(threads);
      break;
    }
    if (!g_api && g_error.empty())
      g_error = std::string("the OpenImageIO module ") + kModuleFile +
                " was not found (looked at " + tried + ")";
  }
  if (!g_api && error) *error = g_error;
  return g_api;
}

}  // namespace

void set_threads(int threads) {
  g_threads = threads;
  std::lock_guard lock(g_mutex);
  if (g_api && threads > 0) g_api->set_threads(threads);
}

bool loaded() {
  std::lock_guard lock(g_mutex);
  return g_api != nullptr;
}

std::string load() {
  std::string error;
  api(&error);
  return error;
}

std::string read_image(const std::string& path, int max_channels, long long max_pixels,
                       cv::Mat& pixels, ImageHeader& header) {
  std::string error;
  const Api* a = api(&error);
  return a ? a->read_image(path, max_channels, max_pixels, pixels, header) : path + ": " + error;
}

}  // namespace oiio_module

std::string write_chart_png(const std::string& path, const std::vector<ChartSeries>& series,
                            const ChartOptions& options) {
  std::string error;
  const oiio_module::Api* a = oiio_module::api(&error);
  return a ? a->write_chart_png(path, series, options) : path + ": " + error;
}

}  // namespace ssdo
