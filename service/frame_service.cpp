#include "service/frame_service.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "formats/camera_io.h"
#include "formats/output_writer.h"
#include "service/file_version.h"
#include "service/frame_list.h"
#include "service/frame_options.h"
#include "service/pipeline.h"
#include "service/request_options.h"
#include "service/sequence.h"
#include "service/view_selection.h"

namespace ssdo {

namespace fs = std::filesystem;

namespace {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char s[32];
  std::strftime(s, sizeof s, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return s;
}

std::string timing(const WorkerResult& r) {
  char s[128];
  std::snprintf(s, sizeof s, "%.0f ms: read %.0f, compute %.0f, write %.0f", r.wall_ms, r.times.read_ms,
                r.times.compute_ms, r.times.write_ms);
  return s;
}

// The frame options of `options` (JSON of FrameOptionArgs), or none when they do not parse.
std::optional<FrameOptionArgs> parsed_options(const nlohmann::json& options) {
  FrameOptionArgs args;
  std::string error;
  if (!apply_json(options, args, error)) return std::nullopt;
  return args;
}

// The options attribute (options_attribute) of a task's options; empty when they do not parse.
std::string options_key(const nlohmann::json& options) {
  const std::optional<FrameOptionArgs> args = parsed_options(options);
  return args ? options_attribute(*args) : std::string();
}

}  // namespace


std::string write_error_file(const std::string& path, const std::string& input, const std::string& error,
                             bool retry, const std::string& version, const std::string& options) {
  nlohmann::json j{{"input", input}, {"error", error}, {"time", utc_now()}, {"retry", retry}};
  if (!version.empty()) j["version"] = version;
  if (!options.empty()) j["options"] = options;
  return write_file_atomically(path, j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

std::string record_frame_failure(const std::string& output, const std::string& error_path, const std::string& input,
                                 const WorkerResult& result, const std::string& version, const std::string& options) {
  remove_output_and_previews(output);
  return write_error_file(error_path, input, result.error, result.transient, version, options);
}

FrameService::FrameService(FrameServiceOptions options)
    : options_(std::move(options)) {
  if (const std::optional<FrameOptionArgs> watch = parsed_options(options_.watch_options)) {
    watch_made_with_ = options_attribute(*watch);
    watch_files_ = option_paths(*watch);
  }
}

FrameService::~FrameService() { stop(); }

void FrameService::start() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (started_) return;
  started_ = true;
  started_at_ = Clock::now();
  for (int i = 0; i < options_.workers; ++i) dispatchers_.emplace_back([this] { dispatch_loop(); });
}

bool FrameService::submit(FrameTask task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_ || tasks_.size() >= options_.queue_capacity) return false;
    task.queued_at = Clock::now();
    tasks_.push_back(std::move(task));
  }
  wake_.notify_one();
  return true;
}

void FrameService::drop_abandoned() {
  std::vector<FrameTask> gone;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = tasks_.begin(); it != tasks_.end();) {
      if (!it->is_abandoned()) {
        ++it;
        continue;
      }
      gone.push_back(std::move(*it));
      it = tasks_.erase(it);
    }
  }
  for (FrameTask& task : gone) drop(task);  // outside the lock: done takes it (end_output)
}

void FrameService::drop(FrameTask& task) {
  log("dropped " + task.input_name() + ": its client closed the connection while it was queued");
  WorkerResult r;
  r.error = "the client closed the connection";
  if (task.done) task.done(r);
}

void FrameService::enqueue_watched(const std::string& reported) {
  // A sidecar stands for its frame (when the frame is there: it may come later).
  std::string input = reported;
  if (const std::string frame = frame_for_sidecar(reported); !frame.empty()) {
    struct stat st {};
    if (::stat(frame.c_str(), &st) != 0) return;
    input = frame;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_ || watched_.count(input)) return;
    if (watched_in_flight_.count(input)) {  // look again when its dispatcher is done
      watched_again_.insert(input);
      return;
    }
    watched_.emplace(input, false);
    watched_order_.push_back(input);
  }
  wake_.notify_one();
}

void FrameService::stop() {
  std::deque<FrameTask> abandoned;
  std::vector<std::thread> threads;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    abandoned.swap(tasks_);
    threads.swap(dispatchers_);
  }
  wake_.notify_all();
  WorkerResult stopping;
  stopping.error = "the service is stopping; the frame was not started";
  for (FrameTask& t : abandoned)
    if (t.done) t.done(stopping);
  for (std::thread& t : threads) t.join();
}

ServiceStats FrameService::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  ServiceStats s;
  s.frames_done = done_;
  s.frames_failed = failed_;
  s.frames_skipped = skipped_;
  s.queue_depth = tasks_.size() + watched_.size();
  s.in_flight = in_flight_;
  s.queue_capacity = options_.queue_capacity;
  s.mean_frame_ms = done_ > 0 ? done_ms_ / double(done_) : 0;
  s.workers = options_.workers;
  s.workers_replaced = replaced_;
  s.frames_retried = retried_;
  s.uptime_s = std::chrono::duration<double>(Clock::now() - started_at_).count();
  return s;
}

bool FrameService::claim_output(const std::string& output, const std::string& input, std::string& owner) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto [it, added] = output_owner_.emplace(output, input);
  owner = it->second;
  return added || it->second == input;
}

bool FrameService::begin_output(const std::string& output) {
  std::lock_guard<std::mutex> lock(mutex_);
  return outputs_in_flight_.insert(output).second;
}

void FrameService::end_output(const std::string& output) {
  std::lock_guard<std::mutex> lock(mutex_);
  outputs_in_flight_.erase(output);
}

void FrameService::log(const std::string& line) {
  std::lock_guard<std::mutex> lock(log_mutex_);
  std::cout << printable(line) << "\n" << std::flush;
}

void FrameService::record(const WorkerResult& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (r.ok()) {
    ++done_;
    done_ms_ += r.wall_ms;
  } else {
    ++failed_;
  }
  if (r.worker_replaced) ++replaced_;
}

void FrameService::dispatch_loop() {
  WorkerProcess worker(options_.limits);
  if (std::string error; !worker.start(error)) log("worker: " + error);
  for (;;) {
    std::unique_lock<std::mutex> lock(mutex_);
    wake_.wait(lock, [&] { return stopping_ || !tasks_.empty() || !watched_order_.empty(); });
    if (stopping_) return;
    if (!tasks_.empty()) {
      FrameTask task = std::move(tasks_.front());
      tasks_.pop_front();
      if (task.is_abandoned()) {  // its client went just before drop_abandoned could take it
        lock.unlock();
        drop(task);
        continue;
      }
      ++in_flight_;
      lock.unlock();
      run_task(worker, task);
    } else {
      const std::string input = watched_order_.front();
      watched_order_.pop_front();
      const bool force = watched_[input];
      watched_.erase(input);
      watched_in_flight_.insert(input);
      ++in_flight_;
      lock.unlock();
      const bool changed = run_watched(worker, input, force);
      lock.lock();
      watched_in_flight_.erase(input);
      const bool again = watched_again_.erase(input) > 0;
      if ((changed || again) && !stopping_ && !watched_.count(input)) {
        watched_[input] = changed;
        watched_order_.push_back(input);
        wake_.notify_one();
      }
    }
    if (!lock.owns_lock()) lock.lock();
    --in_flight_;
  }
}

WorkerResult FrameService::run_with_retries(WorkerProcess& worker, const WorkerJob& job, const FrameTask* task) {
  WorkerResult r = worker.run(job);
  for (int attempt = 1; !r.ok() && r.transient && attempt <= options_.retries; ++attempt) {
    if (task && task->is_abandoned()) {
      log("not retrying " + job.input_path + ": its client closed the connection");
      break;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopping_) break;
      ++retried_;
      if (r.worker_replaced) ++replaced_;
    }
    log("retrying " + job.input_path + " (" + std::to_string(attempt) + " of " + std::to_string(options_.retries) +
        " after a transient failure: " + r.error + ")");
    const double first_ms = r.wall_ms;
    r = worker.run(job);
    r.wall_ms += first_ms;
  }
  return r;
}

namespace {

// `text` with every `from` replaced by `to`.
std::string replace_all(std::string text, const std::string& from, const std::string& to) {
  for (size_t at = text.find(from); !from.empty() && at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

// A request's frame whose file or sidecar was replaced or rewritten while it was computed (not
// the version `found` before): its result may be of the old version. The output is dated back
// behind the new one, as the batch and the watch do, so that a watch or `ssdo process` over
// the folder computes it again; the reply says so.
void warn_if_changed(const std::string& input, const std::string& output, const FrameFiles& found,
                     WorkerResult& r) {
  if (!r.ok() || !changed_since(input, found)) return;
  r.warnings.push_back(mark_out_of_date(output, found)
                           ? "the input or its sidecar changed while it was computed: the result may be of the old "
                             "version; its output is marked out of date"
                           : "the input or its sidecar changed while it was computed: the result may be of the old "
                             "version; ask for it again");
}

}  // namespace

void FrameService::run_task(WorkerProcess& worker, FrameTask& task) {
  const std::string before_key = task.error_path.empty() ? std::string() : frame_version_key(task.input);
  // An inline frame sits in the request's private spool folder: nobody replaces it.
  const std::optional<FrameFiles> found =
      task.inline_name.empty() ? std::optional<FrameFiles>(frame_files(task.input)) : std::nullopt;
  WorkerResult r =
      run_with_retries(worker, {task.input, task.output, task.options, task.neighbours, task.confine}, &task);
  if (found) warn_if_changed(task.input, task.output, *found, r);
  const std::string input_name = task.input_name();
  if (!task.inline_name.empty()) {
    r.error = replace_all(r.error, sidecar_path_for(task.input), "the request's \"sidecar\"");
    r.error = replace_all(r.error, task.input, input_name);
  }
  record(r);
  if (!task.error_path.empty()) {
    std::error_code ec;
    if (r.ok()) fs::remove(task.error_path, ec);
    else record_frame_failure(task.output, task.error_path, input_name, r, before_key, options_key(task.options));
  }
  log(r.ok() ? "ok " + input_name + " -> " + task.output + " (" + timing(r) + ")"
             : "FAILED " + input_name + ": " + r.error);
  for (const std::string& warning : r.warnings) log("  note: " + input_name + ": " + warning);
  if (task.done) task.done(r);
  // A watched frame's output replaced, or failed, by a request (with other options than the
  // watch's, most often): the watch looks at the frame again, and its up-to-date test
  // (watched_frame_done) has it computed again with its own options.
  if (const std::string watched = watched_frame_of(task.output); !watched.empty()) enqueue_watched(watched);
}

std::string FrameService::watched_frame_of(const std::string& output) const {
  if (options_.watch_dir.empty()) return {};
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = output_owner_.find(output);
  if (it == output_owner_.end()) return {};
  const std::string& input = it->second;  // an inline upload's owner is no path: no folder
  const bool watched = fs::path(input).parent_path() == options_.watch_dir && is_frame_file(input) &&
                       output_path_for(input, options_.out_dir) == output;
  return watched ? input : std::string();
}

bool FrameService::run_watched(WorkerProcess& worker, const std::string& input, bool force) {
  const std::string output = output_path_for(input, options_.out_dir);
  const std::string error_path = error_path_for(input, options_.out_dir);
  // Claimed first, up to date or not: a socket request for another frame of the same name
  // is then told of the conflict instead of replacing this frame's output.
  std::string owner;
  const bool claimed = claim_output(output, input, owner);
  // The frames of its sequence in the folder now: one scan of the folder for the up-to-date
  // test and the job.
  const std::vector<NeighbourFrame> neighbours = watch_neighbours(input);
  if (claimed && !force && watched_frame_done(input, output, error_path, neighbours)) {
    count_skipped(input);
    return false;
  }
  const FrameFiles found = frame_files(input);
  const FileVersion& before = found.input;
  const std::string before_key = frame_version_key(input);
  WorkerResult r;
  if (!claimed) {
    r.error = input + ": its output " + output + " is already written for " + owner;
  } else if (!before.exists) {
    // Gone between its event and now: deleted, or renamed away; or a link to nothing.
    std::error_code ec;
    r.error = fs::is_symlink(fs::symlink_status(input, ec))
                  ? input + ": a symbolic link to a missing file (" + fs::read_symlink(input, ec).string() + ")"
                  : input + ": the file was deleted or renamed while queued";
  } else if (before.size == 0) {
    r.error = input + ": empty file (0 bytes)";
  } else {
    // The frames of its sequence already in the folder are its neighbours; the watch
    // folder's own rules: the input, its sidecar and the neighbours inside it (a symbolic
    // link pointing out of it is refused); the service's options are the administrator's.
    r = run_with_retries(worker, {input, output, options_.watch_options, neighbours,
                                  {{options_.watch_dir}, {}, options_.out_dir, {}}});
    if (version_of(input).exists && changed_since(input, found)) {
      // Replaced or rewritten (or its sidecar) while computed: the result may be of the old
      // version. It is dated back, so that a service stopped before the new version's turn
      // computes it again when restarted instead of taking it as up to date.
      if (std::error_code ec; r.ok() && !mark_out_of_date(output, found)) fs::remove(output, ec);
      log("changed while processing, queued again: " + input);
      std::lock_guard<std::mutex> lock(mutex_);
      if (r.worker_replaced) ++replaced_;
      return true;
    }
  }
  record(r);
  finish_watched(input, output, error_path, r, before_key);
  return false;
}

void FrameService::finish_watched(const std::string& input, const std::string& output,
                                  const std::string& error_path, const WorkerResult& r, const std::string& version) {
  std::error_code ec;
  std::string unwritten;  // why the error file could not be written
  if (r.ok()) fs::remove(error_path, ec);
  else unwritten = record_frame_failure(output, error_path, input, r, version, watch_made_with_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (r.ok()) given_up_.erase(input);
    else given_up_.insert(input);
    accounted_[input] = version;
    if (unwritten.empty()) unwritten_failures_.erase(input);
    else unwritten_failures_[input] = version;
  }
  if (r.ok()) log("ok " + input + " -> " + output + " (" + timing(r) + ")");
  else if (unwritten.empty()) log("FAILED " + input + ": " + r.error + " (" + error_path + ")");
  else log("FAILED " + input + ": " + r.error + " (the error file could not be written: " + unwritten + ")");
}

void FrameService::count_skipped(const std::string& input) {
  const std::string version = frame_version_key(input);
  std::lock_guard<std::mutex> lock(mutex_);
  std::string& accounted = accounted_[input];
  if (accounted != version) ++skipped_;
  accounted = version;
}

int FrameService::watch_views() const { return options_.watch_options.value("views", kDefaultViewsPerSide); }
int FrameService::watch_temporal() const { return options_.watch_options.value("temporal", kDefaultTemporalPerSide); }

std::vector<NeighbourFrame> FrameService::watch_neighbours(const std::string& input) const {
  return folder_neighbours(input, neighbour_places(watch_views(), watch_temporal()));
}

bool FrameService::watched_frame_done(const std::string& input, const std::string& output,
                                      const std::string& error_path, const std::vector<NeighbourFrame>& neighbours) {
  if (output_up_to_date_with_sidecar(input, output) && output_up_to_date_with_all(watch_files_, output) &&
      neighbours_older_than(neighbours, output)) {
    const OutputMadeWith made = output_made_with(
        output, watch_made_with_, window_attribute(neighbours, watch_views(), watch_temporal()));
    return (watch_made_with_.empty() || made.same_options) && made.whole &&
           (!options_.watch_options.value("png", false) || made.previews);
  }
  if (failed_without_error_file(input)) return true;
  if (!output_up_to_date_with_sidecar(input, error_path)) return false;
  std::ifstream in(error_path);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  // The frame or its sidecar is not the version that failed (whatever the timestamps say).
  if (j.is_object() && j.contains("version") && j["version"] != frame_version_key(input)) return false;
  // A socket request's other options failed it, not the watch's.
  if (j.is_object() && j.contains("options") && j["options"] != watch_made_with_) return false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (given_up_.count(input)) return true;
  }
  return !(j.is_object() && j.value("retry", false));
}

bool FrameService::failed_without_error_file(const std::string& input) const {
  const std::string version = frame_version_key(input);
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = unwritten_failures_.find(input);
  return it != unwritten_failures_.end() && it->second == version;
}

}  // namespace ssdo
