// The benchmarks' main: Google Benchmark's, after the heap policy of the processes that
// compute frames (core/heap_policy.h), so that a kernel in a warm loop reuses the memory
// its last call freed, as in a worker, instead of faulting it in fresh each call.
#include <benchmark/benchmark.h>

#include "core/heap_policy.h"

int main(int argc, char** argv) {
  ssdo::keep_freed_memory_for_reuse();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
