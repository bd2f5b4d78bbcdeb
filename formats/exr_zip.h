// The block codec of OpenEXR's ZIP and ZIPS compression on libdeflate and ISA-L.
//
// OpenEXR 3.1 inflates and deflates with zlib; libdeflate does the same work on whole
// buffers, faster both ways, and writes streams any zlib reads. At the fastest level
// (kFastestLevel, the writer's default) ISA-L's igzip deflates instead: on a 1080p frame's
// terms 2.4x faster than libdeflate's level 1, for a file 1% larger. The reader and the writer
// move the chunk bytes with OpenEXR (formats/gbuffer_reader, formats/output_writer); this
// file only turns a chunk's packed bytes into its compressed bytes and back.
//
// The transform before deflate is the file format's (OpenEXR "Technical Introduction",
// ZIP compression; ImfZip.cpp): the bytes of the packed block are split into the even- and
// the odd-indexed halves, then each byte is replaced by its difference to the previous one
// plus 128 (mod 256). Deflate's output is a zlib stream (RFC 1950).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/uninitialized.h"

namespace ssdo::exr_zip {

// Deflate levels: 1 (fastest) .. 12 (smallest). Level 1 is ISA-L's level 1; 2 .. 12 are
// libdeflate's.
inline constexpr int kMinLevel = 1;
inline constexpr int kMaxLevel = 12;
inline constexpr int kFastestLevel = kMinLevel;

// Compresses one packed chunk into `compressed` (resized to the stream's size; its
// storage is not zeroed first). Returns
// false when the stream would not be smaller than the packed bytes: the file format then
// stores the chunk uncompressed, and so must the caller. Thread-safe: each thread keeps
// its own compressor per level. ISA-L (level 1) picks its code for the CPU, so its streams
// may differ between CPUs, and on a loaded machine an ISA-L deflate of the same bytes
// rarely picks another match (docs/performance.md, "Output codecs"); every stream inflates
// to the same bytes. libdeflate's levels give the same stream every time.
bool compress(std::span<const uint8_t> packed, int level, UninitializedVector<uint8_t>& compressed);

// Inflates one chunk into `packed`, whose size is the chunk's unpacked size (known from the
// header). False when the stream is damaged or does not inflate to exactly that size.
bool decompress(std::span<const uint8_t> compressed, std::span<uint8_t> packed);

}  // namespace ssdo::exr_zip
