// Frames are decoded and computed in worker processes, never in the process that must
// survive (the batch, the service): a frame that crashes, stalls or exhausts its worker
// becomes that frame's error and the worker is replaced.
//
// A worker is `ssdo worker` started with posix_spawn from /proc/self/exe, with a request
// pipe on its fd 3 and a response pipe on its fd 4 (length-prefixed JSON, see
// service/protocol.h). A request names the input and output paths (frame data never
// crosses a pipe) and carries the frame options (service/request_options.h); the response
// gives the error or the terms written and the per-stage times. The worker lives across
// requests: spawning is paid once, not per frame. Inside the worker: RLIMIT_AS (memory),
// no core files, its own thread budget, and it dies with its parent (PR_SET_PDEATHSIG).
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "formats/exr_header_check.h"
#include "service/pipeline.h"
#include "service/protocol.h"

namespace ssdo {

struct WorkerLimits {
  int threads = 1;                    // kernel and decoder threads of the worker
  int64_t memory_limit_mb = 4096;     // address-space limit of the worker (RLIMIT_AS), MiB; a
                                      // 1080p frame with every term peaks at 510 MiB resident
                                      // and runs under a 1024 MiB limit
  double frame_timeout_s = 300;       // wall time of one frame (read + compute + write)
  int64_t max_pixels = kDefaultMaxPixels;  // larger data windows are refused before decoding (8K x 8K)
};

// Where a job's files may be (service/confined_open.h); the worker opens each of them
// itself, confined, and reads and writes only through the descriptors it opened.
struct Confinement {
  std::vector<std::string> input_roots;   // the input and its NAME.camera.json; empty = anywhere
  std::vector<std::string> option_roots;  // the options' camera and environment files; empty = anywhere
  std::string output_root;                // the output's folder; empty = the output path as given
  // The frames it uses as views and their sidecars; empty = input_roots. An inline frame's
  // input root is its spool folder, its views' the --allow folders.
  std::vector<std::string> view_roots;
  nlohmann::json to_json() const;
  static Confinement from_json(const nlohmann::json& j);
};

struct WorkerJob {
  std::string input_path;
  std::string output_path;
  nlohmann::json options = nlohmann::json::object();  // service/request_options.h keys
  // Frames of the same shot it may use as extra views (with the "views" option).
  std::vector<NeighbourFrame> neighbours;
  // Where the worker may open the job's files (the input, its camera, the neighbours).
  Confinement confine;
};

struct WorkerResult {
  std::string error;                  // empty on success; else the reason (signal, timeout, memory, ...)
  StageTimes times;                   // as measured inside the worker
  double wall_ms = 0;                 // request sent -> response read, as the parent saw it
  double handled_ms = 0;              // request received -> response sent, as the worker saw it
  double peak_rss_mib = 0;            // the worker's peak resident memory so far
  int page_faults = 0;                // the page faults the worker took for this request
  std::vector<std::string> terms;     // terms written
  int width_px = 0, height_px = 0;
  std::vector<std::string> notes;     // the reader's and the sequence context's notes
  std::vector<std::string> warnings;  // the batch's own words on the frame, shown without -v too
  // The shot's window the frame was computed with: views and temporal neighbours per side.
  // Smaller than asked when the asked one did not fit under --memory-limit; window_note then
  // says so and why (shown without -v too: it changes the frame's terms), else it is empty.
  int views_per_side = 0, temporal_per_side = 0;
  std::string window_note;
  bool window_reduced() const { return !window_note.empty(); }
  bool worker_replaced = false;       // the worker died or was killed during this frame
  bool worker_started = false;        // a worker was started for this frame (wall_ms includes it)
  // The worker was killed (a signal, the frame timeout) or the frame ran out of memory
  // (the worker's "out_of_memory", decided from the exception, never from the message):
  // the same frame may succeed on a new worker, so the service tries it again (--retries).
  bool transient = false;
  bool ok() const { return error.empty(); }
};

// The fields of a worker's response (cmd_worker.cpp) into `result`: the error, stage times,
// terms, notes and window, with control characters escaped (printable); transient when
// the worker says the frame ran out of memory ("out_of_memory": true). Fields of another
// type than expected count as absent.
void read_worker_response(const nlohmann::json& j, WorkerResult& result);

// One worker process, started on first use and restarted after it dies. Not thread-safe:
// one owner thread (the batch and the service run one thread per worker).
class WorkerProcess {
 public:
  explicit WorkerProcess(WorkerLimits limits, std::string executable = "/proc/self/exe");
  ~WorkerProcess();  // closes the pipes (the worker exits), then reaps it
  WorkerProcess(const WorkerProcess&) = delete;
  WorkerProcess& operator=(const WorkerProcess&) = delete;

  // Starts the worker now (a service warms its workers up before the first request:
  // loading the executable's libraries takes a few hundred ms). False with a message.
  bool start(std::string& error);

  // Runs one frame. Never throws; every failure is in the result.
  WorkerResult run(const WorkerJob& job);

  // Ends the worker without waiting for it: closes the pipes, and the idle worker exits on
  // its own (the kernel frees its memory, ~0.1 s for a 1080p frame's, after this returns).
  // For a process about to exit, whose end reaps it; the destructor waits instead.
  void release();

  pid_t pid() const { return pid_; }
  int spawn_count() const { return spawns_; }

 private:
  bool spawn(std::string& error);
  void stop(bool kill_now);
  // Reaps the (dead or killed) worker and describes how it ended.
  std::string reap_reason();

  WorkerLimits limits_;
  std::string executable_;
  pid_t pid_ = -1;
  int to_worker_ = -1, from_worker_ = -1;
  int spawns_ = 0;
};

// Arguments of the hidden `ssdo worker` subcommand.
struct WorkerArgs {
  int request_fd = 3, response_fd = 4;
  int threads = 1;
  int64_t memory_limit_mb = 4096;
  int64_t max_pixels = kDefaultMaxPixels;
  int64_t parent_pid = 0;  // exit at once when the parent is already gone
};
int run_worker(const WorkerArgs& args);

// "SIGSEGV (Segmentation fault)" for 11.
std::string signal_description(int signal);

}  // namespace ssdo
