// One owner of parallelism. OpenCV runs nested parallel_for_ calls serially and OpenCV,
// OpenEXR and OpenImageIO each keep their own pool, so a batch either computes several
// frames at once (one worker process per frame, one thread each) or one frame at a time
// with every thread inside it; never both. Measured on 2 cores (README.md, "Batch and
// service"): frames in parallel are faster for 640x360 and for 1080p frames, because
// reading, denoising and writing are partly serial inside a frame.
#pragma once

#include <cstddef>

namespace ssdo {

struct Parallelism {
  int workers = 1;          // worker processes = frames in flight
  int threads_per_frame = 1;
};

// CPUs this process may run on (its affinity mask), at least 1.
int available_cores();

// jobs > 0: that many workers; threads > 0: that many threads per frame; 0 = decide:
// across frames (workers = min(cores, frames), threads = cores / workers). `frames` = how
// many frames the batch will compute (a service passes 0 for "unknown, many").
Parallelism plan_parallelism(int jobs, int threads, size_t frames);

}  // namespace ssdo
