// What a batch tells its user while it runs: on a terminal (stderr is a tty) a progress
// bar with frames/s and ETA, failures printed above it; otherwise one plain line per
// frame on stdout, for farm managers:
//   [3/10] in/a.exr -> out/a.ssdo.exr: ok (412 ms; 2.41 frames/s, ETA 3 s)
//   [4/10] in/b.exr: FAILED: in/b.exr: not an OpenEXR file (...)
//   [5/10] in/c.exr: skipped (output up to date: out/c.ssdo.exr)
// and at the end, on stdout in both modes:
//   done 8, skipped 1, failed 1, 4.21 s
// Thread-safe: the batch's worker threads report concurrently.
#pragma once

#include <mutex>
#include <string>

#include "service/protocol.h"
#include "service/worker_process.h"

namespace ssdo {

// Frames per second of a batch whose `workers` compute side by side: what it measured
// (`computed` frames in `elapsed_s`), or, when more, what its workers give at the mean wall
// time of a computed frame (`mean_frame_ms`, 0 before the first). The measure alone
// undercounts until the workers' first frames end together: two workers whose first frames
// take 1 s each have made 2 frames/s, not 1, when the first ends.
double batch_frames_per_s(int computed, double elapsed_s, int workers, double mean_frame_ms);

class BatchProgress {
 public:
  BatchProgress(int total, int to_compute, int workers, bool bar, bool verbose);
  void skipped(const std::string& input, const std::string& output);
  void finished(const std::string& input, const std::string& output, const WorkerResult& result);
  // Prints the summary line (with "interrupted" and the frames not started when the
  // batch was stopped by a signal). Returns the number of failed frames.
  int summary(bool interrupted);

 private:
  std::string counter();
  void draw_bar();
  double elapsed_s() const;
  double frames_per_s() const;

  std::mutex mutex_;
  const int total_, to_compute_, workers_;
  const bool bar_, verbose_;
  int done_ = 0, skipped_ = 0, failed_ = 0;
  // Parent-seen wall time minus the worker's handling time, of frames run by a warm
  // worker (isolation per frame) and of frames that started their worker (+ start-up).
  double isolation_ms_ = 0, startup_ms_ = 0;
  int warm_frames_ = 0, startups_ = 0;
  double frames_ok_ms_ = 0;  // parent-seen wall time of the frames computed
  int frames_ok_ = 0;
  Clock::time_point start_ = Clock::now();
};

}  // namespace ssdo
