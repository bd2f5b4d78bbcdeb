// Where a test skips itself, and says why; both kinds run in the main build.
//
// SSDO_REFERENCE_MEASUREMENT(): kernel tests that measure an estimator or a filter against
// a brute-force reference with large sample counts (the SSDO oracle, the ray-marched AO, the
// environment's cone filter summed texel by texel) take seconds each in the main build and
// minutes under ASan, while the kernel code they reach runs in the other kernel tests too.
// They measure once: on the instruction set the dispatcher chooses, in the main build. They
// skip themselves in a sanitizer build, and when SSDO_SIMD names an instruction set
// (KernelsOnTheBaselineInstructionSet): every target gives the same bits (simd_test and the
// other kernel tests there hold them to it), so the measurement would only be repeated.
//
// SSDO_SKIP_IN_SANITIZER_BUILD(reason): integration tests that compute a whole shot or
// every preset again to compare two ways of getting it, minutes under ASan over code paths
// that other tests run there.
#pragma once

#include <cstdlib>

#include <gtest/gtest.h>

#include "core/sanitizer_build.h"

#ifdef SSDO_SANITIZER_BUILD
#define SSDO_SKIP_IN_SANITIZER_BUILD(reason) GTEST_SKIP() << "left out of the sanitizer build: " << (reason)
#define SSDO_REFERENCE_MEASUREMENT() \
  GTEST_SKIP() << "a measurement against a brute-force reference: left out of the sanitizer build"
#else
#define SSDO_SKIP_IN_SANITIZER_BUILD(reason) static_cast<void>(0)
#define SSDO_REFERENCE_MEASUREMENT()                                                                    \
  do {                                                                                                  \
    if (const char* simd = std::getenv("SSDO_SIMD"); simd != nullptr && *simd != '\0')                 \
      GTEST_SKIP() << "a measurement against a brute-force reference: made once, on the instruction " \
                   << "set the dispatcher chooses (SSDO_SIMD=" << simd << " gives the same bits)";      \
  } while (0)
#endif
