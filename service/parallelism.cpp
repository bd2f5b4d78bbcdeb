#include "service/parallelism.h"

#include <sched.h>

#include <algorithm>
#include <thread>

#include <OpenEXR/ImfThreading.h>

#include "core/parallel.h"

namespace ssdo {

void apply_thread_budget(int threads) {
  if (threads <= 0) return;
  set_thread_budget(threads);
  Imf::setGlobalThreadCount(threads > 1 ? threads : 0);
}

int available_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof set, &set) == 0) return std::max(1, CPU_COUNT(&set));
  return std::max(1u, std::thread::hardware_concurrency());
}

int frame_threads(int threads) { return std::min(threads, available_cores()); }

Parallelism plan_parallelism(int jobs, int threads, bool service) {
  const int cores = available_cores();
  threads = frame_threads(threads);
  Parallelism p;
  if (jobs > 0) p.workers = jobs;
  else if (threads > 0) p.workers = std::max(1, cores / threads);
  else p.workers = service ? cores : 1;
  p.threads_per_frame = threads > 0 ? threads : std::max(1, cores / p.workers);
  return p;
}

}  // namespace ssdo
