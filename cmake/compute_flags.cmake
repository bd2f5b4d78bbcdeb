# Compile flags of the compute layers (core/, kernels/, the test ray caster) and of the formats
# library's per-sample loops: the interface target ssdo_compute_flags. Included once by the
# top-level CMakeLists.txt.
add_library(ssdo_compute_flags INTERFACE)
# -ffp-contract=off: no fused multiply-adds the source does not write, so 1 and N threads
# and every build of the same source and flags are bit-identical (contraction would round
# differently wherever the compiler chose to fuse).
# -fno-math-errno -fno-trapping-math: the kernels never read errno or floating-point
# exception flags. Without them every sqrt carries a call for negative inputs and floor
# cannot use the vector rounding instruction, which keeps branch-free loops (confidence's
# taps) from vectorising. Results are unchanged: rounding is not touched.
target_compile_options(ssdo_compute_flags INTERFACE -O3 -ffp-contract=off -fno-math-errno -fno-trapping-math)

# Instruction sets of the kernels. One build runs on every machine of its architecture:
# the kernels' hot loops are compiled once per instruction set (Google Highway's
# foreach_target: the baseline, AVX2 and AVX-512 on x86-64; NEON on aarch64) and the
# best one the CPU runs is chosen at run time (core/simd.h), so a binary built on a new
# farm node also runs on an old one. The loops give the same bits on every target:
# -ffp-contract=off above, and no instruction-specific math (the upsample's exp is its own,
# kernels/half_resolution.cpp). Files without a hot loop (presets, the environment's
# one-off tables, metrics) are compiled once, for the baseline.
#   SSDO_SIMD_TARGETS  all (default): the dispatched set above; baseline: only the
#                      baseline (a third of the kernels' compile time); host: only one,
#                      AVX2 (x86-64-v3) as the baseline where the build host runs it, else
#                      the baseline: a binary for the build host (the sanitizer build: one
#                      compilation of the kernels, whose frames then run 3-5x faster than
#                      on the emulated baseline; the baseline's bits are the main build's
#                      simd_test). The formats library's loops dispatch in all three
#                      (core/simd_targets.h).
#   SSDO_ARCH          none (default) or a -march value raising the baseline itself
#                      (e.g. native: a binary for this machine only)
# Extra compile flags of the kernels library only. The sanitizer presets (CMakePresets.json)
# leave UBSan's pointer checks (alignment, null, pointer-overflow) out of the kernels: a check
# on every vector load and store of fully unrolled tap loops made denoise.cpp alone take
# clang 150 s, against 25 s without them. Most of what they would catch there is still
# caught: ASan checks every access's bounds, and a null pointer faults (ASan reports the SEGV
# with its stack). Misaligned scalar accesses are the loss; the kernels' pointers are
# cv::Mat rows of their element type and their own aligned buffers. The arithmetic checks
# (shifts, signed overflow, float-to-int casts, array bounds) stay, and the formats library,
# which reads untrusted bytes, keeps every check.
set(SSDO_KERNEL_FLAGS "" CACHE STRING "Extra compile flags of the kernels library only (the sanitizer presets set them)")
find_package(hwy REQUIRED)
set(SSDO_SIMD_TARGETS "all" CACHE STRING "Instruction sets the kernels are compiled for: all, baseline or host")
set_property(CACHE SSDO_SIMD_TARGETS PROPERTY STRINGS all baseline host)
set(SSDO_ARCH "none" CACHE STRING "Baseline -march of the compute layers: none or a -march value")
if(SSDO_ARCH STREQUAL "auto")  # the former default, still in older build folders' caches
  set_property(CACHE SSDO_ARCH PROPERTY VALUE none)
endif()
target_link_libraries(ssdo_compute_flags INTERFACE hwy::hwy)
# Targets compiled besides the baseline: AVX2 (with FMA, F16C, BMI2) and AVX-512 on x86,
# NEON on Arm. SSSE3/SSE4 and the newer AVX-512 and SVE variants would each add a
# compilation of every dispatched file for little: the loops are memory-bound and
# 8 lanes wide, and use none of the byte permutes, population counts or compressing
# stores that AVX3_DL adds (its kernels timed within 3% of AVX3's, docs/performance.md).
# HWY_DISABLE_PCLMUL_AES: the kernels use no carry-less multiply or AES instruction, so a
# baseline raised by SSDO_ARCH (x86-64-v3 has neither) makes AVX2 the static target;
# without it Highway requires both and keeps the emulated baseline.
target_compile_definitions(ssdo_compute_flags INTERFACE HWY_DISABLE_PCLMUL_AES
  "HWY_DISABLED_TARGETS=(HWY_SSSE3|HWY_SSE4|HWY_AVX3_DL|HWY_SVE|HWY_SVE2|HWY_SVE_256|HWY_SVE2_128)")
if(SSDO_SIMD_TARGETS STREQUAL "baseline" OR SSDO_SIMD_TARGETS STREQUAL "host")
  target_compile_definitions(ssdo_compute_flags INTERFACE HWY_COMPILE_ONLY_STATIC=1)
elseif(NOT SSDO_SIMD_TARGETS STREQUAL "all")
  message(FATAL_ERROR "SSDO_SIMD_TARGETS must be all, baseline or host, not '${SSDO_SIMD_TARGETS}'")
endif()
if(SSDO_SIMD_TARGETS STREQUAL "host" AND SSDO_ARCH STREQUAL "none" AND CMAKE_SYSTEM_PROCESSOR MATCHES "x86_64|AMD64")
  # Highway's own test, the one its run-time dispatch makes.
  include(CheckCXXSourceRuns)
  set(CMAKE_REQUIRED_LIBRARIES hwy::hwy)
  check_cxx_source_runs([[
#include <hwy/targets.h>
int main() { return (hwy::SupportedTargets() & HWY_AVX2) ? 0 : 1; }]] SSDO_HOST_RUNS_X86_64_V3)
  unset(CMAKE_REQUIRED_LIBRARIES)
  if(SSDO_HOST_RUNS_X86_64_V3)
    set(SSDO_ARCH x86-64-v3)  # this configuration only; the cache keeps none
  endif()
  # CMake keeps the check's answer in the build folder's cache: a folder configured on one
  # machine and built on another keeps the first answer. `cmake -U SSDO_HOST_RUNS_X86_64_V3`
  # asks again.
  message(STATUS "ssdo host SIMD check (cached): AVX2 runs here: ${SSDO_HOST_RUNS_X86_64_V3}")
endif()
if(NOT SSDO_ARCH STREQUAL "none")
  set(SSDO_ARCH_FLAG "-march=${SSDO_ARCH}")
  target_compile_options(ssdo_compute_flags INTERFACE ${SSDO_ARCH_FLAG})
endif()
set_property(GLOBAL PROPERTY SSDO_KERNEL_ARCH_FLAG "${SSDO_ARCH_FLAG}")
message(STATUS "ssdo compute layers: SIMD targets ${SSDO_SIMD_TARGETS}, SSDO_ARCH=${SSDO_ARCH}")
