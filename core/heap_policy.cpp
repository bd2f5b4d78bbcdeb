#include "core/heap_policy.h"

#include <malloc.h>

#include <limits>

namespace ssdo {

void keep_freed_memory_for_reuse() {
  ::mallopt(M_ARENA_MAX, 1);
  ::mallopt(M_MMAP_MAX, 0);
  ::mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
}

bool return_free_memory() { return ::malloc_trim(0) != 0; }

}  // namespace ssdo
