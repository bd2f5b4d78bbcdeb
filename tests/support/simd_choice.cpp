// Every test program runs its kernels with the instruction set SSDO_SIMD chooses, as the
// ssdo executable does: SSDO_SIMD=baseline runs the suite on the fallback a CPU without
// AVX2 takes (core/simd.h).
#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/simd.h"

namespace {

const bool kSimdChosen = [] {
  std::string error;
  if (!ssdo::apply_simd_choice(std::getenv("SSDO_SIMD"), error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    std::exit(2);
  }
  return true;
}();

}  // namespace
