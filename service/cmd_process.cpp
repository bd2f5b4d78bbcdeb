// `ssdo process`: a batch over frames, each decoded and computed in a worker process
// (service/worker_process.h). A bad frame is reported and the batch goes on; exit code 1
// if any frame failed (or the batch was interrupted), 0 otherwise (2 for usage errors,
// before any work). SIGINT / SIGTERM / SIGHUP: no new frame starts, frames in flight finish.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <algorithm>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <thread>
#include <tuple>

#include <CLI/CLI.hpp>

#include "formats/output_writer.h"
#include "service/batch_progress.h"
#include "service/cli_options.h"
#include "service/commands.h"
#include "service/file_version.h"
#include "service/frame_list.h"
#include "service/frame_range.h"
#include "service/parallelism.h"
#include "service/request_options.h"
#include "service/sequence.h"
#include "service/view_selection.h"

namespace ssdo {

namespace {

// Inputs -> the ordered frame list of this batch (patterns expanded with --frames),
// then this chunk's slice of it. `all`: the sequence the frames take their neighbours
// from: the whole list (frames outside the chunk are still its frames' neighbours), with
// --shot-frames the patterns' frames of the whole shot (a farm task's frames see those
// outside its range, as in a run of the whole shot).
bool collect_frames(const ProcessArgs& args, std::vector<std::string>& frames, std::vector<std::string>& all,
                    std::string& error) {
  std::vector<int> numbers, shot;
  if (!args.frames.empty() && !parse_frame_ranges(args.frames, numbers, error)) {
    error = "--frames: " + error;
    return false;
  }
  if (!args.shot_frames.empty() && !parse_frame_ranges(args.shot_frames, shot, error)) {
    error = "--shot-frames: " + error;
    return false;
  }
  // `frames` in order, and beside them the sequence their neighbours come from: the same
  // list, but a pattern's frames over the whole shot when --shot-frames gives it.
  std::vector<std::string> plain, sequence;
  auto add_plain = [&]() {
    std::vector<std::string> found;
    if (!expand_inputs(plain, found, error)) return false;
    frames.insert(frames.end(), found.begin(), found.end());
    sequence.insert(sequence.end(), found.begin(), found.end());
    plain.clear();
    return true;
  };
  for (const std::string& input : args.inputs) {
    // A file that exists is that file, whatever '#' or '@' its name holds.
    if (std::error_code ec; !has_frame_pattern(input) || std::filesystem::exists(input, ec)) {
      plain.push_back(input);
      continue;
    }
    if (numbers.empty()) {
      error = input + ": a frame pattern needs --frames, e.g. --frames 1-100";
      return false;
    }
    // Pattern frames are listed even when the file is missing: a missing frame of a
    // requested range is that frame's error, reported like any other (a missing neighbour
    // is skipped with a note).
    if (!add_plain()) return false;
    for (int n : numbers) frames.push_back(expand_frame_pattern(input, n));
    for (int n : shot.empty() ? numbers : shot) sequence.push_back(expand_frame_pattern(input, n));
  }
  if (!add_plain()) return false;
  if (!numbers.empty() && std::none_of(args.inputs.begin(), args.inputs.end(), has_frame_pattern)) {
    error = "--frames selects frames of a pattern (NAME.####.exr), and no input is one";
    return false;
  }
  // A frame listed twice (overlapping ranges, a file named twice) is computed once; two
  // frames that would write one output (the same file name in two folders) are refused
  // before anything is computed: one would silently replace the other.
  frames = each_file_once(frames);
  sequence = each_file_once(sequence);
  std::map<std::string, std::string> writer_of;
  for (const std::string& f : frames) {
    const auto [it, fresh] = writer_of.emplace(output_path_for(f, args.output_dir), f);
    if (!fresh) {
      error = it->second + " and " + f + " would both write " + it->first +
              " (the same file name): process them into different folders (-o)";
      return false;
    }
  }
  all = sequence;
  if (!args.chunk.empty()) {
    int index = 0, count = 0;
    if (!parse_chunk(args.chunk, index, count, error)) return false;
    frames = chunk_slice(frames, index, count);
  }
  return true;
}

// The frames of one worker thread: with extra views, the thread's consecutive slice of
// `todo` in order (each worker reads a neighbour once for the frames around it); without,
// the next frame not yet taken by any thread.
class FrameTurns {
 public:
  FrameTurns(std::atomic<size_t>& next, size_t count, int thread, int threads, bool slices)
      : next_(next), count_(count), slices_(slices) {
    if (!slices) return;
    // chunk_slice's bounds (service/frame_range.h) over the indices of todo.
    next_own_ = count * size_t(thread) / size_t(threads);
    end_own_ = count * size_t(thread + 1) / size_t(threads);
  }
  // The next frame's index into todo; `count` when there is none.
  size_t take() {
    if (!slices_) return std::min(next_.fetch_add(1), count_);
    return next_own_ < end_own_ ? next_own_++ : count_;
  }
  // True when this thread computes todo[index] after the frame taken last.
  bool later(size_t index) const { return slices_ && index >= next_own_ && index < end_own_; }

 private:
  std::atomic<size_t>& next_;
  const size_t count_;
  const bool slices_;
  size_t next_own_ = 0, end_own_ = 0;
};

// The neighbours of each frame to compute (by path), from the whole frame list: a chunk's
// frames see the frames just outside it.
std::map<std::string, std::vector<NeighbourFrame>> neighbours_by_frame(const std::vector<std::string>& all,
                                                                       int places) {
  std::map<std::string, std::vector<NeighbourFrame>> by_frame;
  if (places <= 0) return by_frame;
  const auto lists = sequence_neighbours(all, places);
  for (size_t i = 0; i < all.size(); ++i) by_frame[all[i]] = lists[i];
  return by_frame;
}

// The job of todo[index]: its paths, options and neighbours (which of them this thread
// computes later).
WorkerJob job_for(const std::vector<std::string>& todo, size_t index, const ProcessArgs& args,
                  const nlohmann::json& options, const std::map<std::string, std::vector<NeighbourFrame>>& neighbours,
                  const std::map<std::string, size_t>& todo_index, const FrameTurns& turns) {
  WorkerJob job{todo[index], output_path_for(todo[index], args.output_dir), options, {}, {}};
  const auto it = neighbours.find(todo[index]);
  if (it == neighbours.end()) return job;
  job.neighbours = it->second;
  for (NeighbourFrame& n : job.neighbours) {
    const auto at = todo_index.find(n.path);
    n.computed_later = at != todo_index.end() && turns.later(at->second);
  }
  return job;
}

// `frames` in the order of their shots: by sequence, then frame number (names without a
// number by name). Each worker takes a consecutive run of the list and reads a neighbour
// once for the frames around it, so frames given out of order (a shell's list, mixed
// padding: "s.0003" sorts before "s.1" by name) would read and compute neighbours again.
void in_shot_order(std::vector<std::string>& frames) {
  auto key = [](const std::string& f) {
    const std::optional<SequencePlace> place = sequence_place(f);
    return place ? std::make_tuple(place->sequence, place->number, f) : std::make_tuple(f, 0L, f);
  };
  std::stable_sort(frames.begin(), frames.end(),
                   [&](const std::string& a, const std::string& b) { return key(a) < key(b); });
}

// The neighbour list of `frame` (none outside a sequence).
const std::vector<NeighbourFrame>& neighbours_of(const std::map<std::string, std::vector<NeighbourFrame>>& neighbours,
                                                 const std::string& frame) {
  static const std::vector<NeighbourFrame> none;
  const auto it = neighbours.find(frame);
  return it == neighbours.end() ? none : it->second;
}

}  // namespace

int run_process(const ProcessArgs& args) {
  std::vector<std::string> frames, all;
  std::string error;
  if (!collect_frames(args, frames, all, error)) {
    std::cerr << "ssdo process: " << error << "\n";
    return 2;
  }
  // No frame anywhere in the inputs is an error (on a farm, a share not mounted); a chunk or
  // range with none of them is not (the last tasks of a shot split finer than its frames).
  if (all.empty()) {
    std::cerr << "ssdo process: no frames (*.exr) in the inputs: an empty folder, or one not mounted?\n";
    return 1;
  }
  if (frames.empty()) std::cerr << "ssdo process: no frames to process in this chunk or range\n";
  std::error_code ec;
  std::filesystem::create_directories(args.output_dir, ec);
  if (ec) {
    std::cerr << "ssdo process: cannot create output folder " << args.output_dir << ": " << ec.message() << "\n";
    return 2;
  }
  if (const int n = remove_stale_temp_files(args.output_dir); n > 0)
    std::cerr << "ssdo process: removed " << n << " temp files of an interrupted run in " << args.output_dir << "\n";

  const bool bar = ::isatty(STDERR_FILENO) == 1;
  // With views or temporal filtering, a frame's neighbours are read (and their raw terms
  // computed) once per worker: each worker takes a contiguous slice of the frames, in order.
  const int places = neighbour_places(args.options.compute.views, args.options.compute.temporal);
  const auto neighbours = neighbours_by_frame(all, places);
  // An output newer than its frame, its neighbours, their sidecars and the files the options
  // name (--camera, --env) is up to date when it was made with this run's options too.
  std::vector<std::string> todo, up_to_date;
  // Frames whose existing output is of another version of the frame, its neighbours or the
  // options: a frame that fails now does not leave it in place (it would pass for the
  // result of the frame that failed).
  std::set<std::string> stale;
  const std::string made_with = options_attribute(args.options);
  const std::vector<std::string> option_files = option_paths(args.options);
  int other_options = 0, cut_short = 0, not_ssdo = 0, no_previews = 0;
  for (const std::string& f : frames) {
    const std::string output = output_path_for(f, args.output_dir);
    const bool current = output_up_to_date_with_sidecar(f, output) &&
                         neighbours_older_than(neighbours_of(neighbours, f), output) &&
                         output_up_to_date_with_all(option_files, output);
    const OutputMadeWith made =
        current ? output_made_with(output, made_with,
                                   window_attribute(neighbours_of(neighbours, f), args.options.compute.views,
                                                    args.options.compute.temporal))
                : OutputMadeWith{};
    const bool same_options = made.same_options;
    const bool whole = same_options && made.whole && (!args.options.png || made.previews);
    if (std::error_code ec; !(same_options && made.whole) && std::filesystem::exists(output, ec)) stale.insert(f);
    other_options += !args.force && current && made.from_ssdo && !same_options;
    not_ssdo += !args.force && current && !made.from_ssdo;
    cut_short += !args.force && same_options && !made.whole;
    no_previews += !args.force && same_options && made.whole && !whole;
    (whole && !args.force ? up_to_date : todo).push_back(f);
  }
  if (places > 0) in_shot_order(todo);
  // Why outputs found are computed again, one line per reason.
  auto say = [](int count, const char* why) {
    if (count > 0)
      std::cerr << "ssdo process: " << count << (count == 1 ? " output was " : " outputs were ") << why
                << ": computed again\n";
  };
  say(other_options, "made with other options, other neighbouring frames or another ssdo version than this run's");
  say(not_ssdo, "not readable as ssdo's (a damaged file, or another program's in its place)");
  say(no_previews, "missing some of their --png previews");
  say(cut_short, "cut short (an interrupted copy, or a crash before the data reached the disk)");

  const Parallelism plan = plan_parallelism(args.jobs, args.options.compute.threads, false);
  WorkerLimits limits = args.limits;
  limits.threads = plan.threads_per_frame;
  const int n_threads = int(std::min<size_t>(size_t(plan.workers), todo.size()));  // a worker per thread
  BatchProgress progress(int(frames.size()), int(todo.size()), n_threads, bar, args.verbose);
  for (const std::string& f : up_to_date) progress.skipped(f, output_path_for(f, args.output_dir));
  if (args.verbose)
    std::cerr << "ssdo process: " << todo.size() << (todo.size() == 1 ? " frame, " : " frames, ") << n_threads
              << (n_threads == 1 ? " worker process x " : " worker processes x ") << plan.threads_per_frame
              << (plan.threads_per_frame == 1 ? " thread\n" : " threads\n");
  const nlohmann::json options = to_json(args.options);
  std::map<std::string, size_t> todo_index;
  for (size_t i = 0; i < todo.size(); ++i) todo_index.emplace(todo[i], i);

  // SIGINT / SIGTERM / SIGHUP are taken by this thread with sigtimedwait (blocked everywhere, so
  // no handler and no global flag); the worker threads check `stop` between frames. The
  // last worker thread to finish wakes this one with SIGUSR1 (the batch ends when its
  // last frame does, not at the next tick).
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stop_signals, s);
  sigset_t waited = stop_signals;
  sigaddset(&waited, SIGUSR1);
  ::pthread_sigmask(SIG_BLOCK, &waited, nullptr);
  ::signal(SIGPIPE, SIG_IGN);
  const pthread_t main_thread = ::pthread_self();

  // Each frame's input and sidecar as the batch found them: a frame changed while the batch
  // runs may have been read before or after the change (workers read ahead).
  std::vector<FrameFiles> found(todo.size());
  for (size_t i = 0; i < todo.size(); ++i) found[i] = frame_files(todo[i]);
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  std::atomic<int> running{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < n_threads; ++t) {
    ++running;
    threads.emplace_back([&, t]() {
      {
        WorkerProcess worker(limits);
        FrameTurns turns(next, todo.size(), t, n_threads, places > 0);
        for (size_t i; !stop && (i = turns.take()) < todo.size();) {
          const WorkerJob job = job_for(todo, i, args, options, neighbours, todo_index, turns);
          WorkerResult r = worker.run(job);
          if (r.ok() && changed_since(todo[i], found[i]))
            r.warnings.push_back(mark_out_of_date(job.output_path, found[i])
                                  ? "the input or its sidecar changed while the batch ran: its output is marked out "
                                    "of date, and a rerun computes it again"
                                  : "the input or its sidecar changed while the batch ran: rerun with --force");
          if (!r.ok() && stale.count(todo[i])) {
            remove_output_and_previews(job.output_path);
            r.warnings.push_back("its output of an earlier version of the frame, its neighbours or the options was "
                                 "removed");
          }
          progress.finished(job.input_path, job.output_path, r);
        }
        // Every output is in place: the batch need not wait for the worker to exit.
        worker.release();
      }
      if (--running == 0) ::pthread_kill(main_thread, SIGUSR1);
    });
  }
  const timespec tick{0, 100 * 1000 * 1000};
  while (running > 0) {
    const int sig = ::sigtimedwait(&waited, nullptr, &tick);
    if (sig != SIGINT && sig != SIGTERM && sig != SIGHUP) continue;
    if (stop) {
      // A second signal: the user will not wait. The workers die with this process
      // (PR_SET_PDEATHSIG); the next run into the folder removes their temp files.
      std::cerr << "\nssdo process: stopped at once (a second signal): frames in flight abandoned\n" << std::flush;
      std::_Exit(128 + sig);
    }
    stop = true;
    std::cerr << "\nssdo process: stopping: frames in flight finish, no new frame starts (a second signal stops "
                 "at once)\n";
  }
  for (std::thread& t : threads) t.join();
  const int failed = progress.summary(stop);
  return failed > 0 || stop ? 1 : 0;
}

namespace {

// --shot-frames: --frames outside the shot are dropped (a farm's last task may overshoot).
// False when nothing is left to do or on a usage error (then `exit_code` says which).
bool clip_to_shot(ProcessArgs& process, const std::string& shot_frames, int& exit_code) {
  if (shot_frames.empty()) return true;
  if (process.frames.empty()) {
    exit_code = usage_error("--shot-frames needs --frames");
    return false;
  }
  std::string clipped, error;
  size_t dropped = 0;
  if (!clip_frame_ranges(process.frames, shot_frames, clipped, error, &dropped)) {
    exit_code = usage_error("--frames " + process.frames + " --shot-frames " + shot_frames + ": " + error);
    return false;
  }
  if (dropped > 0)
    std::cerr << "ssdo process: --frames " << process.frames << " within the shot's frames " << shot_frames << ": "
              << (clipped.empty() ? "none, nothing to do" : clipped) << "\n";
  exit_code = 0;
  process.frames = clipped;
  process.shot_frames = shot_frames;
  return !clipped.empty();
}

}  // namespace

Command register_process(CLI::App& app) {
  struct State {
    ProcessArgs process;
    std::string config, shot_frames;
  };
  auto st = std::make_shared<State>();
  ProcessArgs& p = st->process;
  CLI::App* cmd = app.add_subcommand(
      "process", "Compute the selected terms for frames and write one EXR per frame "
                 "(OUT/NAME.ssdo.exr). A frame whose output is newer than its input and was made with the same options "
                 "by the same ssdo version is skipped (--force computes it again).");
  cmd->add_option("inputs", p.inputs,
                  "EXR frames, folders of frames, or frame patterns (shot.####.exr, shot.%04d.exr) with --frames")
      ->required();
  cmd->add_option("--frames", p.frames, "Frame numbers for patterns, oiiotool-style: 1-100, 1-100x2, 1-10,20,30");
  cmd->add_option("--chunk", p.chunk,
                  "Process only the I-th of N equal slices of the frame list (I/N, I from 1): one task of a farm job");
  cmd->add_option("-o,--out", p.output_dir, "Output folder")->required();
  cmd->add_flag("--force", p.force, "Recompute frames whose output is up to date");
  cmd->add_option("--config", st->config,
                  "JSON file of frame options (those 'ssdo options' lists: what decides a frame's output, not "
                  "--frames, --jobs or -o): their long names without '--' as keys, e.g. "
                  "{\"method\": \"hbao\", \"terms\": \"all\"}; flags given override it")
      ->check(CLI::ExistingFile);
  cmd->add_flag("-v,--verbose", p.verbose,
                "Per-stage timings (read, compute, write, isolation), the worker's peak memory and page faults, "
                "and the worker plan");
  add_frame_options(*cmd, p.options);
  add_worker_limits(*cmd, p.jobs, p.limits);
  cmd->add_option("--shot-frames", st->shot_frames,
                  "The shot's frames, e.g. 1-240: --frames outside them are dropped (a farm's last task may ask for "
                  "frames past the shot's end); a missing frame inside them still fails");
  return {cmd, [st, cmd] {
            std::string error;
            if (!frame_options_over_config(*cmd, st->config, st->process.options, error)) return usage_error(error);
            int exit_code = 0;
            if (!clip_to_shot(st->process, st->shot_frames, exit_code)) return exit_code;
            return run_process(st->process);
          }};
}

}  // namespace ssdo
