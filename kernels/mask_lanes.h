// A mask image's bytes as a lane mask, for the kernels' lane loops (Highway).
//
// Included once per instruction set (by the kernels' foreach_target files, after
// hwy/highway.h), into that target's namespace, as kernels/integer_power.h.
#if defined(SSDO_KERNELS_MASK_LANES_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef SSDO_KERNELS_MASK_LANES_H_
#undef SSDO_KERNELS_MASK_LANES_H_
#else
#define SSDO_KERNELS_MASK_LANES_H_
#endif

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

// The lanes of a full float vector whose mask bytes (one per pixel, from `mask` on) are
// nonzero.
inline hwy::HWY_NAMESPACE::Mask<hwy::HWY_NAMESPACE::ScalableTag<float>> foreground_lanes(const uint8_t* mask) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::ScalableTag<float> d;
  const hn::RebindToSigned<decltype(d)> di;
  const hn::Rebind<uint8_t, decltype(d)> d8;
  const auto m = hn::BitCast(di, hn::PromoteTo(hn::RebindToUnsigned<decltype(d)>(), hn::LoadU(d8, mask)));
  return hn::RebindMask(d, hn::Gt(m, hn::Zero(di)));
}

// The same for the pixels left in a row from `mask` on (left >= 1): the lanes at or past
// the row's end are not foreground (nothing past it is read).
inline hwy::HWY_NAMESPACE::Mask<hwy::HWY_NAMESPACE::ScalableTag<float>> foreground_lanes(const uint8_t* mask,
                                                                                         size_t left) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::ScalableTag<float> d;
  if (left >= hn::Lanes(d)) return foreground_lanes(mask);
  HWY_ALIGN uint8_t tail[HWY_MAX_BYTES / sizeof(float)] = {};  // the widest target's lanes
  std::copy(mask, mask + left, tail);
  return foreground_lanes(tail);
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_MASK_LANES_H_
