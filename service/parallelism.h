// One owner of parallelism. OpenCV runs nested parallel_for_ calls serially and OpenCV
// and OpenEXR each keep their own pool, so frames are computed either one at
// a time with every thread inside the frame, or several at once (one worker process per
// frame, one thread each); never both.
// Measured on 2 cores shared with other jobs (docs/service.md, "Workers"): a batch
// of 640x360 frames runs at the same speed both ways (within noise), a batch of 1080p
// frames 7 % faster one frame at a time, which also needs one worker (one start-up, one
// frame in memory). So a batch computes one frame at a time by default. A service runs
// one worker per core instead: concurrent requests are served side by side and a frame
// that stalls until --frame-timeout holds one worker, not the service.
#pragma once

#include <cstddef>

namespace ssdo {

struct Parallelism {
  int workers = 1;          // worker processes = frames in flight
  int threads_per_frame = 1;
};

// Sizes the pools of this process once, where a worker or an in-process command starts:
// OpenCV's (the kernels, core/parallel.h set_thread_budget) and OpenEXR's (decoding and
// compression; one thread = in the calling thread, no pool). threads > 0: that many;
// 0: both as the libraries start (OpenCV every core, OpenEXR none). Frames then pass the
// same count as their thread budget (FrameRequest::threads), which never resizes a pool.
void apply_thread_budget(int threads);

// CPUs this process may run on (its affinity mask), at least 1.
int available_cores();

// jobs > 0: that many workers; threads > 0: that many threads per frame, at most the
// cores. Otherwise, for a batch (`service` false): one worker with every core; for a
// service: one worker per core, one thread each. `threads` alone sets the workers to cores
// / threads.
Parallelism plan_parallelism(int jobs, int threads, bool service);

// A frame's thread count at most the cores available (0, the default, stays 0): threads
// beyond them cannot run at once (TBB, OpenCV's backend, never starts more workers than
// cores), and each costs a stack and its scratch.
int frame_threads(int threads);

}  // namespace ssdo
