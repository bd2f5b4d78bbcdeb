// The core of `ssdo serve`: a bounded queue of frames, a fixed set of dispatcher threads
// each owning one worker process (service/worker_process.h), the bookkeeping that makes
// watched frames processed exactly once, and the service's statistics.
//
// Two sources feed it:
// - the socket: submit() puts a task in a queue of `queue_capacity` entries or refuses
//   (the client is answered "busy"); its callback gets the result;
// - the watcher: enqueue_watched() records a path in a set (one entry per file, however
//   often it is reported). A watched frame is computed when neither its output nor its
//   error file is at least as new as its last change, checked when a dispatcher takes it,
//   so rescans and events never compute a frame twice, and restarts skip finished frames.
//   A camera sidecar (NAME.camera.json) counts as part of its frame: its arrival or change
//   queues the frame again, and an output or error file older than it is stale. A socket
//   request that wrote or failed a watched frame's output queues the frame again too: an
//   output or error file of other options than the watch's is computed again.
// Socket tasks go first (someone is waiting for them). A transient failure (the worker
// killed, timed out or out of memory: WorkerResult::transient) is tried again on a new
// worker, `retries` times at most. Failed frames get OUT/NAME.error.json (written through
// a temp file) and lose their old output (it described an older version of the input);
// a later success removes the error file. An error file of a transient failure says
// "retry": true, and a restarted service computes such a frame again.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/protocol.h"
#include "service/worker_process.h"

namespace ssdo {

struct FrameServiceOptions {
  std::string out_dir;                   // canonical output folder
  std::string watch_dir;                 // canonical watch folder: watched inputs and sidecars stay in it
  nlohmann::json watch_options = nlohmann::json::object();  // options of watched frames
  int workers = 1;                       // worker processes (dispatcher threads)
  WorkerLimits limits;
  size_t queue_capacity = 64;            // socket tasks waiting; beyond: "busy"
  int retries = 2;                       // new attempts after a transient failure
};

// One frame asked for over the socket.
struct FrameTask {
  std::string input, output;             // resolved paths
  std::string error_path;                // NAME.error.json to write on failure; empty = none
  // For an inline upload: its name in messages ("inline frame NAME") instead of the private
  // spool path the worker read it from, and of its sidecar there the request's "sidecar".
  std::string inline_name;
  nlohmann::json options = nlohmann::json::object();
  std::vector<NeighbourFrame> neighbours;  // the request's "views" (resolved)
  Confinement confine;                   // where the worker may open the task's files
  std::function<void(const WorkerResult&)> done;  // called once, from a dispatcher thread
  Clock::time_point queued_at = Clock::now();
  // Set when the client has gone (closed its connection): a queued task is dropped (done
  // gets an error, nothing is written; FrameService::drop_abandoned), a failed one is not
  // tried again. Null: never.
  std::shared_ptr<const std::atomic<bool>> abandoned;
  bool is_abandoned() const { return abandoned && abandoned->load(); }
  // The input as messages name it: its path, or "inline frame NAME" for an upload (the
  // spool's paths mean nothing to the client, and are gone once it is answered).
  std::string input_name() const { return inline_name.empty() ? input : "inline frame " + inline_name; }
};

struct ServiceStats {
  long frames_done = 0, frames_failed = 0, frames_skipped = 0;
  size_t queue_depth = 0, in_flight = 0, queue_capacity = 0;
  double mean_frame_ms = 0;              // wall time of successful frames
  int workers = 0;
  long workers_replaced = 0;
  long frames_retried = 0;               // attempts after a transient failure
  double uptime_s = 0;
};

class FrameService {
 public:
  explicit FrameService(FrameServiceOptions options);
  ~FrameService();  // stop()

  void start();
  // False when the queue is full or the service is stopping (the task is not run).
  bool submit(FrameTask task);
  // Takes the queued socket tasks whose client has gone out of the queue (their `done` gets
  // an error; nothing is written): nobody waits for them, so they neither count in the
  // queue's depth nor hold a place another client could have. A task already computing
  // finishes.
  void drop_abandoned();
  // Considers a watched input (see above).
  void enqueue_watched(const std::string& input);
  // No new task starts; queued socket tasks are answered "service stopping"; frames in
  // flight finish; dispatchers and workers end. Idempotent.
  void stop();
  ServiceStats stats() const;
  // Records that `output` is written for `input`. False, with `owner` = the other input,
  // when another input already claimed it in this run: two inputs of one name in different
  // folders (a/x.exr, b/x.exr -> OUT/x.ssdo.exr) must not replace each other's result.
  bool claim_output(const std::string& output, const std::string& input, std::string& owner);
  // Marks `output` as being computed for a socket request until end_output. False when
  // another request's frame is computing it now (two uploads of one name at once would
  // each be told "ok" while one replaces the other's result).
  bool begin_output(const std::string& output);
  void end_output(const std::string& output);

 private:
  void dispatch_loop();
  // Answers a task whose client has gone, and logs it.
  void drop(FrameTask& task);
  // True when the input changed while it was computed (to be computed again).
  bool run_watched(WorkerProcess& worker, const std::string& input, bool force);
  void run_task(WorkerProcess& worker, FrameTask& task);
  // The frame of the watch folder whose output `output` is (the input that claimed it);
  // empty when none.
  std::string watched_frame_of(const std::string& output) const;
  // Runs the job, again on a new worker after a transient failure (options_.retries times),
  // unless `task` (when given) is abandoned by then.
  WorkerResult run_with_retries(WorkerProcess& worker, const WorkerJob& job, const FrameTask* task = nullptr);
  // True when a watched input needs no computing: its output, or an error file that is
  // final (not a transient failure, or one this run already gave up on), is up to date.
  bool watched_frame_done(const std::string& input, const std::string& output, const std::string& error_path,
                          const std::vector<NeighbourFrame>& neighbours);
  // Records a watched frame's result (its error file, or none; what this run remembers of
  // it) and logs it; `version` is frame_version_key of the input it read.
  void finish_watched(const std::string& input, const std::string& output, const std::string& error_path,
                      const WorkerResult& r, const std::string& version);
  // Whether this version of a watched input failed and its error file could not be written.
  bool failed_without_error_file(const std::string& input) const;
  // Counts a watched frame found up to date as skipped, once per version of it: --poll's
  // rescans and repeated events find the same frame again and again.
  void count_skipped(const std::string& input);
  // The watch's window (its options' --views and --temporal) and a watched frame's
  // neighbours: the frames of its sequence in the folder now.
  int watch_views() const;
  int watch_temporal() const;
  std::vector<NeighbourFrame> watch_neighbours(const std::string& input) const;
  void record(const WorkerResult& r);
  void log(const std::string& line);

  const FrameServiceOptions options_;
  // The options attribute of watched frames' outputs (request_options.h): an output made
  // with other options is computed again. Empty when watch_options do not parse.
  std::string watch_made_with_;
  std::vector<std::string> watch_files_;  // the files the watch options name (--camera, --env)
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<FrameTask> tasks_;
  std::deque<std::string> watched_order_;
  std::map<std::string, bool> watched_;  // pending watched input -> forced (changed while computed)
  std::set<std::string> watched_in_flight_;
  std::set<std::string> watched_again_;  // reported again while in flight
  std::map<std::string, std::string> output_owner_;  // output -> the input it is written for
  std::set<std::string> outputs_in_flight_;           // begin_output .. end_output
  bool stopping_ = false, started_ = false;
  std::vector<std::thread> dispatchers_;
  size_t in_flight_ = 0;
  std::set<std::string> given_up_;       // inputs whose transient failure this run gave up on
  // Watched input -> the version (frame_version_key) this run computed, failed or counted as
  // skipped: finding that version up to date again is not another skipped frame.
  std::map<std::string, std::string> accounted_;
  // Watched input -> the version that failed when its error file could not be written (a
  // name too long, a full disk): no file records the failure, so this run remembers it, and
  // rescans and events do not compute the frame again and again (a restart does, once).
  std::map<std::string, std::string> unwritten_failures_;
  long done_ = 0, failed_ = 0, skipped_ = 0, replaced_ = 0, retried_ = 0;
  double done_ms_ = 0;
  Clock::time_point started_at_ = Clock::now();
  std::mutex log_mutex_;
};

// Writes NAME.error.json ({"input", "error", "time", "retry", "version", "options"}) through
// a temp file and rename; "retry" is true for a transient failure (a restart tries the frame
// again); "version" (left out when empty) is frame_version_key of the input the failure
// read; "options" (left out when empty) the options attribute it was computed with
// (request_options.h: options_attribute), so that a watch folder's frame failed by a
// request's other options is computed again with the watch's. Returns why it could not be
// written (a name longer than the file system allows, a full disk); empty when written.
std::string write_error_file(const std::string& path, const std::string& input, const std::string& error,
                             bool retry = false, const std::string& version = {}, const std::string& options = {});

// Records a failed frame: removes its output (an older version's result, which would
// otherwise sit beside the newer error) and its previews, and writes its error file with the
// input's version and the options. Returns write_error_file's answer.
std::string record_frame_failure(const std::string& output, const std::string& error_path, const std::string& input,
                                 const WorkerResult& result, const std::string& version, const std::string& options);

}  // namespace ssdo
