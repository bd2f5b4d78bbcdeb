// What this build of ssdo can enforce.
//
// Sanitizer builds (core/sanitizer_build.h) reserve terabytes of shadow address space when
// the process starts: an address-space limit (RLIMIT_AS, the workers' --memory-limit) below
// that makes every later mapping fail, so that the worker could not even start a thread.
// Their workers run without the limit; everything else (frame timeouts, pixel limits,
// isolation) is the same.
#pragma once

#include "core/sanitizer_build.h"

namespace ssdo {

#ifdef SSDO_SANITIZER_BUILD
inline constexpr bool kMemoryLimitEnforced = false;
#else
inline constexpr bool kMemoryLimitEnforced = true;
#endif

}  // namespace ssdo
