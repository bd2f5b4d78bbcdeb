// SSDO_SANITIZER_BUILD is defined in builds under a sanitizer (CMakePresets.json presets
// asan, fuzz and tsan): clang reports them through __has_feature, GCC through
// __SANITIZE_ADDRESS__ / __SANITIZE_THREAD__. Their allocators replace malloc's heap and
// they reserve terabytes of shadow address space.
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
