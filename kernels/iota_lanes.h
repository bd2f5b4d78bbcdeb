// Lanes first, first + 1, ... (Highway's Iota) for a `first` known only at run time.
// Highway's x86 Iota writes the lanes to memory one by one and loads the vector: a load
// that the store buffer cannot forward, a stall per call, inside the lane loops that call
// it per vector. Iota(d, 0) is a constant the compiler folds; adding `first` to it is one
// addition, with the same values (integers, and floats for integer `first` below 2^24).
//
// Included once per instruction set (by the kernels' foreach_target files, after
// hwy/highway.h), into that target's namespace, as kernels/integer_power.h.
#if defined(SSDO_KERNELS_IOTA_LANES_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef SSDO_KERNELS_IOTA_LANES_H_
#undef SSDO_KERNELS_IOTA_LANES_H_
#else
#define SSDO_KERNELS_IOTA_LANES_H_
#endif

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

template <class D, typename T>
HWY_INLINE hwy::HWY_NAMESPACE::Vec<D> iota_lanes(D d, T first) {
  namespace hn = hwy::HWY_NAMESPACE;
  return hn::Add(hn::Set(d, hn::TFromD<D>(first)), hn::Iota(d, 0));
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_IOTA_LANES_H_
