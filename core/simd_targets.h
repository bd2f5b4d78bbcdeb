// The instruction sets of the per-sample loops over whole frames (formats' exr_zip and
// foreground_pass, core's half_samples and sample_planes): the kernels'
// (cmake/compute_flags.cmake) and SSSE3 besides. Highway's x86 baseline is scalar: on the
// kernels' set alone a CPU without AVX2 (before 2013) would run these loops one sample at
// a time, 3-4x slower than with 128-bit vectors (zip's prefix sum, the foreground pass).
// They are small, so the one more compilation costs seconds.
// Included by each such file before Highway, with the file itself the only one in its
// translation unit (formats/CMakeLists.txt keeps them out of unity batches; core has none).
//
// Whatever SSDO_SIMD_TARGETS says of the kernels (cmake/compute_flags.cmake): a build whose
// kernels are compiled for the baseline only (the sanitizer build) still reads and writes
// frames on the best instruction set, and its core and formats tests run every target
// (tests/support/each_simd_target.h).
#pragma once

#undef HWY_COMPILE_ONLY_STATIC
#undef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS \
  (HWY_SSE4 | HWY_AVX3_DL | HWY_SVE | HWY_SVE2 | HWY_SVE_256 | HWY_SVE2_128)
