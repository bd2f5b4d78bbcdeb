#include "core/heap_policy.h"

#include <malloc.h>

#include <algorithm>
#include <limits>
#include <string_view>

namespace ssdo {

void keep_freed_memory_for_reuse() {
  ::mallopt(M_ARENA_MAX, 1);
  ::mallopt(M_MMAP_MAX, 0);
  ::mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
}

bool return_free_memory() { return ::malloc_trim(0) != 0; }

std::string worker_glibc_tunables(const char* inherited) {
  constexpr std::string_view kName = "glibc.malloc.hugetlb=";
  const std::string current = inherited ? inherited : "";
  // Tunables are name=value pairs separated by ':'.
  for (size_t at = 0; at <= current.size();) {
    const size_t end = std::min(current.find(':', at), current.size());
    if (std::string_view(current).substr(at, end - at).starts_with(kName)) return current;
    at = end + 1;
  }
  return current + (current.empty() ? "" : ":") + std::string(kName) + "1";
}

}  // namespace ssdo
