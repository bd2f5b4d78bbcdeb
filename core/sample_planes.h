// The channels of interleaved pixels split into one plane per channel: as a scanline chunk
// stores them (OpenEXR "Technical Introduction", "Pixel Data": per line, each channel's
// samples of the whole line; formats/output_writer.cpp), and as the upsample reads a half
// grid's rows (kernels/half_resolution.cpp). In its own file because its loop runs over
// every sample of a frame and is compiled once per instruction set and dispatched at run
// time (core/simd.h).
#pragma once

#include <cstdint>

namespace ssdo::sample_planes {

// planes[c][x] = pixels[x * channels + c] for x < n and c < channels (channels >= 1), the
// samples' bits copied: half samples (their bits) or floats (moved, never computed on, so
// that NaN payloads are kept).
void split(const uint16_t* pixels, int64_t n, int channels, uint16_t* const* planes);
void split(const float* pixels, int64_t n, int channels, float* const* planes);

}  // namespace ssdo::sample_planes
