#include "core/half_samples.h"

#include "core/simd_targets.h"  // before Highway

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "core/half_samples.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <cstring>

// Imath's software conversion, the one OpenEXR's own (baseline) build runs, whatever this
// file's baseline: with F16C in it (a baseline raised by SSDO_ARCH), Imath's inline
// conversion would be the hardware's, which quiets signalling NaNs.
#pragma push_macro("__F16C__")
#undef __F16C__
#include <Imath/half.h>
#pragma pop_macro("__F16C__")

HWY_BEFORE_NAMESPACE();
namespace ssdo::half_samples::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

// Targets whose float16 conversions are the hardware's: F16C on x86 (part of Highway's
// AVX2 and AVX-512 targets) and AArch64's FCVT. Both round to nearest even as Imath does,
// and converting from half is exact as Imath's table is, so every finite value and
// infinity gets Imath's bits; a NaN may not (the hardware quiets a signalling NaN), so a
// group holding one goes through Imath. Highway's software conversions on the other
// targets truncate instead of rounding: there Imath converts every sample.
// (A macro, set again for each target: the other targets' vector types do not compile the
// loops.)
#undef SSDO_HARDWARE_HALF
#if (HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX2 && !defined(HWY_DISABLE_F16C)) || \
    (HWY_ARCH_ARM_A64 && HWY_TARGET == HWY_NEON)
#define SSDO_HARDWARE_HALF 1
#else
#define SSDO_HARDWARE_HALF 0
#endif

// Half's largest finite value.
constexpr float kHalfMax = 65504.0f;

// Imath's conversion (round to nearest even) of n consecutive floats into half bits,
// saturated to +-kHalfMax (NaN stays NaN).
void to_half_imath(const float* in, int64_t n, uint16_t* out) {
  for (int64_t x = 0; x < n; ++x) {
    const float v = in[x] > kHalfMax ? kHalfMax : in[x] < -kHalfMax ? -kHalfMax : in[x];
    out[x] = half(v).bits();
  }
}

// Imath's conversion of n half samples (little-endian bits) to floats `pixel_floats` floats
// apart: its table, which OpenEXR's copyIntoFrameBuffer uses through half's float operator
// unless OpenEXR is built for F16C.
void to_float_imath(const uint8_t* from, int64_t n, float* to, size_t pixel_floats) {
  for (int64_t x = 0; x < n; ++x) {
    uint16_t bits;
    std::memcpy(&bits, from + 2 * x, 2);
    to[size_t(x) * pixel_floats] = imath_half_to_float_table[bits].f;
  }
}

// to_half (half_samples.h) on this target.
void to_half_lanes(const float* in, int n, uint16_t* out) {
  int64_t x = 0;
#if SSDO_HARDWARE_HALF
  const hn::ScalableTag<float> df;
  const hn::Rebind<hwy::float16_t, decltype(df)> dh;
  const int64_t lanes = int64_t(hn::Lanes(df));
  for (; x + lanes <= n; x += lanes) {
    const auto v = hn::LoadU(df, in + x);
    if (!hn::AllFalse(df, hn::IsNaN(v))) {
      to_half_imath(in + x, lanes, out + x);
      continue;
    }
    const auto saturated = hn::Min(hn::Max(v, hn::Set(df, -kHalfMax)), hn::Set(df, kHalfMax));
    hn::StoreU(hn::DemoteTo(dh, saturated), dh, reinterpret_cast<hwy::float16_t*>(out + x));
  }
#endif
  to_half_imath(in + x, n - x, out + x);
}

// to_float (half_samples.h) on this target.
void to_float_lanes(const uint8_t* from, int64_t n, float* to, size_t pixel_floats) {
  int64_t x = 0;
#if SSDO_HARDWARE_HALF
  const hn::ScalableTag<float> df;
  const hn::Rebind<hwy::float16_t, decltype(df)> dh;
  const hn::Rebind<int16_t, decltype(df)> di;
  const hn::Repartition<uint8_t, decltype(di)> du8;
  const auto magnitude_bits = hn::Set(di, int16_t{0x7fff});
  const auto infinity_bits = hn::Set(di, int16_t{0x7c00});
  const int64_t lanes = int64_t(hn::Lanes(df));
  for (; x + lanes <= n; x += lanes) {
    const auto h = hn::BitCast(di, hn::LoadU(du8, from + 2 * x));
    float* out = to + size_t(x) * pixel_floats;
    // A NaN's exponent is all ones and its mantissa not 0: its magnitude is above
    // infinity's. Magnitudes are at most 0x7fff, so the signed comparison is the unsigned one.
    if (!hn::AllFalse(di, hn::Gt(hn::And(h, magnitude_bits), infinity_bits))) {
      to_float_imath(from + 2 * x, lanes, out, pixel_floats);
      continue;
    }
    const auto v = hn::PromoteTo(df, hn::BitCast(dh, h));
    if (pixel_floats == 1) {
      hn::StoreU(v, df, out);
      continue;
    }
    HWY_ALIGN float samples[HWY_MAX_BYTES / sizeof(float)];
    hn::Store(v, df, samples);
    for (int64_t i = 0; i < lanes; ++i) out[size_t(i) * pixel_floats] = samples[i];
  }
#endif
  to_float_imath(from + 2 * x, n - x, to + size_t(x) * pixel_floats, pixel_floats);
}

}  // namespace
}  // namespace ssdo::half_samples::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::half_samples {

HWY_EXPORT(to_half_lanes);
HWY_EXPORT(to_float_lanes);

void to_half(const float* in, int n, uint16_t* out) {
  HWY_DYNAMIC_DISPATCH(to_half_lanes)(in, n, out);
}

void to_float(const uint8_t* from, int64_t n, float* to, size_t pixel_floats) {
  HWY_DYNAMIC_DISPATCH(to_float_lanes)(from, n, to, pixel_floats);
}

}  // namespace ssdo::half_samples
#endif  // HWY_ONCE
