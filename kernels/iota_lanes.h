// Lane coordinates: lanes first, first + 1, ... (Highway's Iota) for a `first` known only at
// run time, the pixel centres they stand for, and floor(log2) of floats from their bits (a
// float and its lanes alike).
//
// Iota: lanes first, first + 1, ... for a `first` known only at run time.
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

#include <bit>
#include <cstdint>

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

template <class D, typename T>
HWY_INLINE hwy::HWY_NAMESPACE::Vec<D> iota_lanes(D d, T first) {
  namespace hn = hwy::HWY_NAMESPACE;
  return hn::Add(hn::Set(d, hn::TFromD<D>(first)), hn::Iota(d, 0));
}

// The pixel centres first + 0.5, first + stride + 0.5, ... of the lanes of the float
// vector type df (the pixel space's convention: pixel x covers [x, x + 1)), exact for
// coordinates below 2^24.
template <class DF>
HWY_INLINE hwy::HWY_NAMESPACE::Vec<DF> pixel_centres_lanes(DF df, int32_t first, int32_t stride = 1) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::RebindToSigned<DF> di;
  const auto x = stride == 1 ? iota_lanes(di, first)
                             : hn::Add(hn::Mul(hn::Iota(di, 0), hn::Set(di, stride)), hn::Set(di, first));
  return hn::Add(hn::ConvertTo(df, x), hn::Set(df, 0.5f));
}

// floor(log2 v) of a positive normal float v: its biased exponent less 127. Zero,
// subnormal and negative values give negative results, inf and NaN 128 or more (and a
// negative NaN a negative one): values their callers clamp or mask.
inline int32_t floor_log2(float v) { return (std::bit_cast<int32_t>(v) >> 23) - 127; }

// floor_log2 of floats, lane by lane: the same bits.
template <class DI, class VF>
HWY_INLINE hwy::HWY_NAMESPACE::Vec<DI> floor_log2_lanes(DI di, VF v) {
  namespace hn = hwy::HWY_NAMESPACE;
  return hn::Sub(hn::ShiftRight<23>(hn::BitCast(di, v)), hn::Set(di, 127));
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_IOTA_LANES_H_
