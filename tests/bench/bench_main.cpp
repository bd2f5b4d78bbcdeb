// The benchmarks' main: Google Benchmark's, after the heap policy of the processes that
// compute frames (core/heap_policy.h), so that a kernel in a warm loop reuses the memory
// its last call freed, as in a worker, instead of faulting it in fresh each call; with the
// instruction set SSDO_SIMD chooses (SSDO_SIMD=avx2 times an AVX2 node's code on an AVX-512
// machine).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/heap_policy.h"
#include "core/simd.h"

int main(int argc, char** argv) {
  ssdo::keep_freed_memory_for_reuse();
  if (std::string error; !ssdo::apply_simd_choice(std::getenv("SSDO_SIMD"), error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 2;
  }
  benchmark::AddCustomContext("simd", ssdo::simd_target());
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
