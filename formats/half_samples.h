// Half-float samples as EXR files store them (IEEE binary16, little-endian) to and from
// the kernels' floats, with exactly OpenEXR's bits: Imath's conversions (its table from
// half, round to nearest even to half), through F16C eight samples at a time where the CPU
// has it (the same bits; groups holding a NaN go through Imath, whose NaN bits F16C may
// not keep).
#pragma once

#include <cstddef>
#include <cstdint>

namespace ssdo::half_samples {

// n consecutive floats to half bits.
void to_half(const float* in, int n, uint16_t* out);

// n half samples (little-endian bytes at `from`) to floats `pixel_floats` floats apart.
void to_float(const uint8_t* from, int64_t n, float* to, size_t pixel_floats);

}  // namespace ssdo::half_samples
