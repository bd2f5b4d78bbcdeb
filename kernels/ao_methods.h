// Internal: the per-method cores behind compute_ao(). Each is defined in its own file
// (ao_<method>.cpp); inputs and settings are already validated, outputs allocated.
#pragma once

#include "kernels/ao.h"

namespace ssdo::detail {

void ao_hemisphere(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi, int nthreads);
void ao_hbao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi, int nthreads);
void ao_gtao(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi, int nthreads);
void ao_raymarch(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi, int nthreads);

}  // namespace ssdo::detail

// In a method's file, after its per-instruction-set code (`#if HWY_ONCE`, in ssdo::detail):
// defines the core above as the call of that code for the best instruction set the CPU runs
// (core/simd.h).
#define SSDO_AO_METHOD_DISPATCH(name)                                                                     \
  HWY_EXPORT(name);                                                                                       \
  void name(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi, int nthreads) { \
    HWY_DYNAMIC_DISPATCH(name)(in, s, out, roi, nthreads);                                                \
  }
