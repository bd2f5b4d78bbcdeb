// What this build of ssdo can enforce.
//
// Sanitizer builds (CMakePresets.json presets asan, fuzz and tsan) reserve terabytes of
// shadow address space when the process starts: an address-space limit (RLIMIT_AS, the
// workers' --memory-limit) below that makes every later mapping fail, so that the worker
// could not even start a thread. Their workers run without the limit; everything else
// (frame timeouts, pixel limits, isolation) is the same.
#pragma once

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define SSDO_SANITIZER_BUILD 1
#endif
#endif
#if !defined(SSDO_SANITIZER_BUILD) && (defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__))
#define SSDO_SANITIZER_BUILD 1
#endif

namespace ssdo {

#ifdef SSDO_SANITIZER_BUILD
inline constexpr bool kMemoryLimitEnforced = false;
#else
inline constexpr bool kMemoryLimitEnforced = true;
#endif

}  // namespace ssdo
