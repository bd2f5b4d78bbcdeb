// The frames the kernel benchmarks time: the shared cornell dump (640x360) and the shared
// perf1080 dump (1920x1080), read once per process; without ../shared, the Cornell-like
// scene of the reference ray caster rendered at the same sizes.
#pragma once

#include "core/gbuffer.h"

namespace ssdo::bench {

// width 640 or 1920: the frame of that width, with view-space positions.
const GBuffer& frame(int width);

}  // namespace ssdo::bench
