# Compile flags of the compute layers (core/, kernels/, the test ray caster): the interface
# target ssdo_compute_flags. Included once by the top-level CMakeLists.txt.
add_library(ssdo_compute_flags INTERFACE)
# -ffp-contract=off: no fused multiply-adds the source does not write, so 1 and N threads
# and every build of the same source and flags are bit-identical (contraction would round
# differently wherever the compiler chose to fuse).
# -fno-math-errno -fno-trapping-math: the kernels never read errno or floating-point
# exception flags. Without them every sqrt carries a call for negative inputs and floor
# cannot use the vector rounding instruction, which keeps branch-free loops (confidence's
# taps) from vectorising. Results are unchanged: rounding is not touched.
target_compile_options(ssdo_compute_flags INTERFACE -O3 -ffp-contract=off -fno-math-errno -fno-trapping-math)

# Instruction set of the kernels (their loops are written to vectorise: 8 floats per AVX2
# register instead of 4 with the x86-64 baseline's SSE2).
#   auto (default)  x86-64-v3 (AVX2, FMA, BMI2) when the compiler accepts it and the build
#                   machine runs it (the product is built where it runs), else the baseline
#   none            the compiler's default (portable x86-64 binaries)
#   <any other>     passed as -march=<value>, e.g. native or x86-64-v4
# x86-64-v3 rather than native: the binaries also run on any AVX2 node of a farm, and the
# kernels gain nothing measurable from AVX-512 (memory-bound taps, 8-wide rows).
set(SSDO_ARCH "auto" CACHE STRING "Kernels' -march: auto, none or a -march value")
if(SSDO_ARCH STREQUAL "auto")
  include(CheckCXXSourceRuns)
  set(CMAKE_REQUIRED_FLAGS "-march=x86-64-v3")
  check_cxx_source_runs([=[
    int main() {
      __builtin_cpu_init();
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
             __builtin_cpu_supports("bmi2") ? 0 : 1;
    }]=] SSDO_HOST_RUNS_X86_64_V3)
  unset(CMAKE_REQUIRED_FLAGS)
  if(SSDO_HOST_RUNS_X86_64_V3)
    set(SSDO_ARCH_FLAG "-march=x86-64-v3")
  endif()
elseif(NOT SSDO_ARCH STREQUAL "none")
  set(SSDO_ARCH_FLAG "-march=${SSDO_ARCH}")
endif()
if(SSDO_ARCH_FLAG)
  target_compile_options(ssdo_compute_flags INTERFACE ${SSDO_ARCH_FLAG})
endif()
set_property(GLOBAL PROPERTY SSDO_KERNEL_ARCH_FLAG "${SSDO_ARCH_FLAG}")
message(STATUS "ssdo compute layers: SSDO_ARCH=${SSDO_ARCH} -> ${SSDO_ARCH_FLAG}")
