// The instruction set the kernels run with. Their hot loops are compiled for several
// (cmake/compute_flags.cmake: the baseline, AVX2 and AVX-512 on x86-64, NEON on Arm) and
// Google Highway dispatches each call to the best one this CPU runs. Every target gives
// the same output bits.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace ssdo {

// The target the kernels dispatch to on this CPU, by Highway's name ("AVX2", "AVX3",
// "NEON", or "EMU128"/"SCALAR" for the portable baseline).
std::string simd_target();

// Every instruction set the build holds code for, best first, comma-separated.
std::string simd_targets_compiled();

// From now on the kernels run their baseline code, the one every CPU of the architecture
// runs (as on a machine without AVX2): to test that fallback, or to compare against it.
// Call before any kernel runs; not thread-safe with running kernels.
void use_baseline_simd();

// Undoes use_baseline_simd(): the best instruction set this CPU runs again.
void use_best_simd();

// The baseline's name (what simd_target() returns after use_baseline_simd()).
std::string simd_baseline_target();

// Every instruction set the build holds code for and this CPU runs, best first (the
// baseline last): the ones use_simd_target() takes.
std::vector<std::string> simd_targets_runnable();

// From now on the kernels run the named instruction set (a name of simd_targets_runnable(),
// case-insensitive: "avx2" on an AVX-512 machine runs what an AVX2 farm node runs). False,
// changing nothing, for a name the build or the CPU lacks. Call before any kernel runs.
bool use_simd_target(std::string_view name);

// What the SSDO_SIMD environment variable asks for (`value`): "" or "best" the best,
// "baseline" the baseline, else a target's name (use_simd_target). False, with the reason
// in `error`, for anything else.
bool apply_simd_choice(const char* value, std::string& error);

}  // namespace ssdo
