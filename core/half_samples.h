// Half-float samples as EXR files store them (IEEE binary16, little-endian) to and from
// the kernels' floats, with exactly OpenEXR's bits: Imath's conversions (its table from
// half, round to nearest even to half), a vector of samples at a time through the CPU's
// half conversions where it has them (F16C with AVX2/AVX-512, AArch64; the same bits:
// groups holding a NaN go through Imath, whose NaN bits the hardware may not keep). One
// exception: floats beyond half's range (|v| >= 65520, infinities included) saturate to
// +-65504, half's largest, instead of rounding to infinity: a term is never made infinite
// by its storage (a sky brighter than half can hold writes its largest value).
#pragma once

#include <cstddef>
#include <cstdint>

namespace ssdo::half_samples {

// n consecutive floats to half bits (beyond half's range: +-65504).
void to_half(const float* in, int n, uint16_t* out);

// n half samples (little-endian bytes at `from`) to floats `pixel_floats` floats apart.
void to_float(const uint8_t* from, int64_t n, float* to, size_t pixel_floats);

}  // namespace ssdo::half_samples
