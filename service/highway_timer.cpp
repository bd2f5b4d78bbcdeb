// Highway's shared library (libhwy.so 1.0.x, as Debian ships it) calibrates the timer of its
// nanobenchmark when it is loaded: a static initializer calls hwy::platform::TimerResolution(),
// which times 65,536 back-to-back reads of the cycle counter, about 5 ms of every process's
// start here (each `ssdo` command, and each worker it spawns: two per single-frame `process`).
// The initializer calls it through the library's procedure linkage table, so this
// executable's definition, exported like every symbol a linked library also defines, is the
// one it binds (tests/integration/startup_test.cpp checks the binding). The value only feeds
// nanobenchmark's sample counts: the ssdo executable times nothing with it (its benchmarks
// are Google Benchmark programs that do not link this file), and the kernels' dispatch
// (hwy::SupportedTargets) does not read it.
#include <cstdint>

namespace hwy::platform {

// One tick: the finest resolution a counter can have; nothing in this program reads it.
uint64_t TimerResolution() { return 1; }

}  // namespace hwy::platform
