// The frames the kernel benchmarks time: the shared cornell dump (640x360) and the shared
// perf1080 dump (1920x1080), read once per process; without ../shared, the Cornell-like
// scene of the reference ray caster rendered at the same sizes. And the environment map
// of those frames' world.
#pragma once

#include "core/gbuffer.h"
#include "kernels/environment.h"

namespace ssdo::bench {

// width 640 or 1920: the frame of that width, with view-space positions.
const GBuffer& frame(int width);

// The shared frames' world (docs/usage.md, "Environment light"; examples/env_equirect.exr):
// t = clamp((d.z + 0.4) / 0.8, 0, 1), L = (1 - t) bottom + t top, as a 512x256 equirect
// built in memory (the file's layout), so that no environment file is read.
cv::Mat sky_equirect();
// An environment of that map, built once per process.
const Environment& sky_environment();

}  // namespace ssdo::bench
