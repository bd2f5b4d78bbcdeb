// A frame's inputs completed for the kernels: what the reader (formats/gbuffer_reader.h)
// reports missing or unusable is rebuilt from depth here, so that formats stays free of
// geometry and every kernel finds normals (and positions when asked for) in the G-buffer.
#pragma once

#include <string>

#include "formats/gbuffer_reader.h"

namespace ssdo {

// After a successful read_gbuffer (a failed read is left as it is):
// - no normals in the frame (normal_view empty): every normal reconstructed from depth
//   (kernels/normals.h);
// - foreground pixels with a zero normal (normal_missing): those normals replaced by the
//   reconstructed ones, noted in info.notes; normal_missing is released;
// - positions asked for but absent (info.positions_missing): computed from depth
//   (kernels/positions.h), recorded in info.uses.
// `threads` as ReadOptions::threads (0 = OpenCV's pool, 1 = serial). Never throws: a
// failure (out of memory) becomes frame.error, with the G-buffer released, as a failed read.
void complete_gbuffer(ReadResult& frame, int threads);

// read_gbuffer, then complete_gbuffer with the read's threads: the frame every kernel
// computes on.
ReadResult read_frame(const std::string& path, const ReadOptions& options = {});

}  // namespace ssdo
