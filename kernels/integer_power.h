// Powers for the normal lobes. c^n for an integer n in [0, 256] by squaring from the most
// significant bit, for any type
// with * (a float, or a Highway vector of floats): one association, so a scalar and a
// vector lane give the same bits. `one` is the type's 1. The normal lobes of the denoise and
// the temporal filter (max(0, n . n_tap)^normal_power): a runtime std::pow per tap costs
// more than the rest of their weights together.
//
// Included once per instruction set (by the kernels' foreach_target files, after
// hwy/highway.h), into that target's namespace: a vector's * inlines only into code
// compiled for the same target. Hence Highway's per-target guard instead of #pragma once.
#if defined(SSDO_KERNELS_INTEGER_POWER_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef SSDO_KERNELS_INTEGER_POWER_H_
#undef SSDO_KERNELS_INTEGER_POWER_H_
#else
#define SSDO_KERNELS_INTEGER_POWER_H_
#endif

#include <cmath>

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

template <class T>
inline T integer_power(T c, unsigned n, T one) {
  T r = one;
  for (int bit = 8; bit >= 0; --bit) {  // n <= 256 = 2^8
    r = r * r;
    if ((n >> bit) & 1u) r = r * c;
  }
  return r;
}

// c^power for c > 0 and power in [0, 256], as the normal lobes take it: integer powers by
// integer_power, others with std::pow (a runtime exponent no default takes). A float, or
// each lane of a vector of tag d: the same bits either way.
inline float power_of(float c, float power) {
  const unsigned n = unsigned(power);
  return float(n) == power ? integer_power(c, n, 1.0f) : std::pow(c, power);
}
template <class D>
hwy::HWY_NAMESPACE::Vec<D> power_of(D d, hwy::HWY_NAMESPACE::Vec<D> c, float power) {
  namespace hn = hwy::HWY_NAMESPACE;
  const unsigned n = unsigned(power);
  if (float(n) == power) return integer_power(c, n, hn::Set(d, 1.0f));
  HWY_ALIGN float lanes[hn::MaxLanes(D())];
  hn::Store(c, d, lanes);
  for (size_t i = 0; i < hn::Lanes(d); ++i) lanes[i] = std::pow(lanes[i], power);
  return hn::Load(d, lanes);
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_INTEGER_POWER_H_
