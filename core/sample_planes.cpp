#include "core/sample_planes.h"

#include <algorithm>

#include "core/simd_targets.h"  // before Highway

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "core/sample_planes.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

// A vector of pixels at a time (Highway's de-interleaving loads of 2, 3 or 4 channels, the
// images' channel counts), the scalar loop for the rest and for other counts. Copies only:
// every target gives the same bytes.
HWY_BEFORE_NAMESPACE();
namespace ssdo::sample_planes::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

template <class T>
void split_lanes(const T* pixels, int64_t n, int channels, T* const* planes) {
  const hn::ScalableTag<T> d;
  const int64_t lanes = int64_t(hn::Lanes(d));
  int64_t x = 0;
  using V = hn::Vec<decltype(d)>;
  if (channels == 1) {
    std::copy_n(pixels, n, planes[0]);
    return;
  }
  if (channels == 2) {
    for (; x + lanes <= n; x += lanes) {
      V a, b;
      hn::LoadInterleaved2(d, pixels + 2 * x, a, b);
      hn::StoreU(a, d, planes[0] + x), hn::StoreU(b, d, planes[1] + x);
    }
  } else if (channels == 3) {
    for (; x + lanes <= n; x += lanes) {
      V a, b, c;
      hn::LoadInterleaved3(d, pixels + 3 * x, a, b, c);
      hn::StoreU(a, d, planes[0] + x), hn::StoreU(b, d, planes[1] + x), hn::StoreU(c, d, planes[2] + x);
    }
  } else if (channels == 4) {
    for (; x + lanes <= n; x += lanes) {
      V a, b, c, e;
      hn::LoadInterleaved4(d, pixels + 4 * x, a, b, c, e);
      hn::StoreU(a, d, planes[0] + x), hn::StoreU(b, d, planes[1] + x), hn::StoreU(c, d, planes[2] + x);
      hn::StoreU(e, d, planes[3] + x);
    }
  }
  for (; x < n; ++x)
    for (int c = 0; c < channels; ++c) planes[c][x] = pixels[x * channels + c];
}

}  // namespace

void split16(const uint16_t* pixels, int64_t n, int channels, uint16_t* const* planes) {
  split_lanes(pixels, n, channels, planes);
}
void split32(const float* pixels, int64_t n, int channels, float* const* planes) {
  split_lanes(pixels, n, channels, planes);
}

}  // namespace ssdo::sample_planes::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::sample_planes {

HWY_EXPORT(split16);
HWY_EXPORT(split32);

void split(const uint16_t* pixels, int64_t n, int channels, uint16_t* const* planes) {
  HWY_DYNAMIC_DISPATCH(split16)(pixels, n, channels, planes);
}
void split(const float* pixels, int64_t n, int channels, float* const* planes) {
  HWY_DYNAMIC_DISPATCH(split32)(pixels, n, channels, planes);
}

}  // namespace ssdo::sample_planes
#endif  // HWY_ONCE
