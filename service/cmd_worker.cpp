// `ssdo worker` (hidden): the process that decodes and computes frames for the batch and
// the service (see service/worker_process.h). Reads requests from fd 3, answers on fd 4,
// exits when the request pipe closes.
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <exception>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>

#include "core/heap_policy.h"
#include "formats/exr_header_check.h"
#include "formats/oiio_module.h"
#include "service/build_features.h"
#include "service/parallelism.h"
#include "service/commands.h"
#include "service/job_files.h"
#include "service/protocol.h"
#include "service/request_options.h"
#include "service/sequence_context.h"
#include "service/worker_process.h"

namespace ssdo {

namespace {

constexpr size_t kMaxRequestBytes = size_t(1) << 20;
// Resolved option sets kept (the environment map is loaded once per set).
constexpr size_t kMaxCachedOptionSets = 8;
// A worker with no request for this long returns its free heap memory to the system.
constexpr double kIdleTrimSeconds = 1.0;

// The response descriptor, for the last words of a worker ending on an uncaught
// exception (std::terminate runs no destructors and has no arguments).
int g_response_fd = -1;
int64_t g_memory_limit_mb = 0;
// Address space released when the last words are written: an uncaught std::bad_alloc
// means the limit is reached, and the message itself needs memory.
void* g_last_words_reserve = nullptr;
constexpr size_t kLastWordsReserveBytes = size_t(1) << 20;
std::atomic_flag g_terminating = ATOMIC_FLAG_INIT;

std::string describe_memory_error(const std::string& error, ResourceFailure exhausted, int64_t limit_mb);

// Writes a framed message (service/protocol.h) with no allocation.
void write_static_message(int fd, const char* text) {
  const size_t n = std::strlen(text);
  unsigned char frame[4];
  encode_length(uint32_t(n), frame);
  if (::write(fd, frame, sizeof frame) == ssize_t(sizeof frame)) (void)!::write(fd, text, n);
}

// True when a request arrives on fd within `seconds` (or the pipe closes, or poll fails:
// the read that follows reports it).
bool request_within(int fd, double seconds) {
  pollfd p{fd, POLLIN, 0};
  int r;
  while ((r = ::poll(&p, 1, int(seconds * 1000.0))) < 0 && errno == EINTR) {
  }
  return r != 0;
}

[[noreturn]] void terminate_with_last_words() {
  // One thread writes; another reaching here meanwhile waits for the exit.
  if (g_terminating.test_and_set()) {
    for (;;) ::pause();
  }
  ::free(g_last_words_reserve);
  g_last_words_reserve = nullptr;
  ResourceFailure exhausted = ResourceFailure::none;
  try {
    std::string what = "an unknown exception";
    if (const std::exception_ptr e = std::current_exception()) {
      try {
        std::rethrow_exception(e);
      } catch (const std::bad_alloc&) {
        what = "out of memory (std::bad_alloc)";
        exhausted = ResourceFailure::memory;
      } catch (const std::exception& ex) {
        what = ex.what();
        exhausted = resource_failure(ex);
      } catch (...) {
      }
    }
    const std::string message = to_wire(nlohmann::json{
        {"ok", false},
        {"exiting", true},
        {"error", describe_memory_error("worker aborted: uncaught exception: " + what, exhausted, g_memory_limit_mb)}});
    if (g_response_fd >= 0) write_message(g_response_fd, message, deadline_in(1.0));
  } catch (...) {
    // Not even the reserve was enough: a message that needs no memory.
    if (g_response_fd >= 0)
      write_static_message(g_response_fd, exhausted == ResourceFailure::memory
                                              ? "{\"ok\":false,\"exiting\":true,\"error\":\"worker aborted: out of "
                                                "memory (std::bad_alloc) under the worker's --memory-limit\"}"
                                              : "{\"ok\":false,\"exiting\":true,\"error\":\"worker aborted: "
                                                "uncaught exception (and out of memory for its message)\"}");
  }
  ::_exit(134);
}

// Starts the threads of every pool the worker uses and waits (up to `until`) until they
// run, so that they start before the address-space limit: a thread's start is not a
// frame's memory, and a pool thread that cannot start, or cannot allocate as it starts,
// ends the whole process instead of failing the frame. TBB, OpenCV's parallel_for_
// backend, creates its workers on first use. OpenEXR's pool starts its threads in
// setGlobalThreadCount, and they allocate nothing until they decode.
void start_pool_threads(int threads, Deadline until) {
  if (threads > 1) {
    // Strips that wait for each other: all `threads` run at once, so TBB has its workers.
    std::atomic<int> running{0};
    cv::parallel_for_(
        cv::Range(0, threads),
        [&](const cv::Range& r) {
          running += r.end - r.start;
          while (running.load() < threads && Clock::now() < until) std::this_thread::yield();
        },
        threads);
  }
}

// The request's "neighbours" ([{"path", "offset", "later"}], service/worker_process.h).
std::vector<NeighbourFrame> neighbours_of(const nlohmann::json& j) {
  std::vector<NeighbourFrame> out;
  if (!j.contains("neighbours") || !j["neighbours"].is_array()) return out;
  for (const nlohmann::json& n : j["neighbours"])
    if (n.is_object() && n.value("path", nlohmann::json()).is_string() && n.value("offset", 0) != 0)
      out.push_back({n["path"].get<std::string>(), n.value("offset", 0), n.value("later", false), {}, {}});
  return out;
}

// Memory a frame needs besides its decoded channels, per pixel: a lower bound (the G-buffer's
// float depth and normal, the term computed, the reader's conversion of one channel), so
// that a frame refused here could never have been computed under the limit. (A 1080p frame
// with every term peaks at about 250 bytes per pixel, worker_process.h.)
constexpr int64_t kWorkingBytesPerPixel = 64;

// The refusal of an EXR whose decode alone, estimated from its headers (`check`), needs more
// than the worker's memory limit (a highly compressed file declaring a large data window
// would otherwise fail in the middle of decoding with a misleading message); empty when it
// may fit, or when the headers are unsound (the reader then says why).
std::string memory_estimate_refusal(const std::string& path, const ExrHeaderCheck& check, int64_t limit_mb) {
  if (limit_mb <= 0 || !check.ok()) return {};
  for (const ExrPartLayout& part : check.parts) {
    const int64_t bytes = part.decoded_bytes() + part.pixels() * kWorkingBytesPerPixel;
    if (bytes <= (limit_mb << 20)) continue;
    return path + ": the frame needs an estimated " + std::to_string(bytes >> 20) + " MiB (" +
           std::to_string(part.max_x - part.min_x + 1) + " x " + std::to_string(part.max_y - part.min_y + 1) +
           " pixels: " + std::to_string(part.channels) + " channels decoded at " +
           std::to_string(part.bytes_per_pixel) + " bytes per pixel, and at least " +
           std::to_string(kWorkingBytesPerPixel) + " bytes per pixel to compute), over the worker's memory limit of " +
           std::to_string(limit_mb) + " MiB (--memory-limit)";
  }
  return {};
}

// The pixels of a frame's first part from its headers; 0 when they are unsound (the reader
// then says why).
int64_t frame_pixels(const ExrHeaderCheck& check) {
  return check.ok() && !check.parts.empty() ? check.parts.front().pixels() : 0;
}

// The error of a frame that ran out of memory or threads, with the worker's limit to raise.
std::string describe_memory_error(const std::string& error, ResourceFailure exhausted, int64_t limit_mb) {
  const bool no_memory = exhausted == ResourceFailure::memory;
  // Threads (OpenEXR's and OpenCV's pools) cannot get their stacks under RLIMIT_AS.
  const bool no_thread = exhausted == ResourceFailure::thread;
  if (!no_memory && !no_thread) return error;
  return error + (no_memory ? " (out of memory: the frame needs more than the worker's limit of "
                            : " (no memory for a thread under the worker's limit of ") +
         std::to_string(limit_mb) + " MiB, see --memory-limit)";
}

// A shot's frames keep their neighbours in memory (service/sequence_context.h: views and
// raw terms of a window of frames), several times one frame's memory. Under --memory-limit
// that window may not fit where the frame alone does. The worker then halves the window
// (views and temporal neighbours per side: 2 -> 1 -> 0, alone) until the frame fits, with a
// note, and computes every later frame of the shot at least as large with that window: a
// shot whose window of 2 per side does not fit keeps the views and the temporal filtering
// of a smaller one rather than losing both (a 1080p shot, --terms ao --preset low: about 320
// MiB of address space with 2 per side, 280 with 1; tests/integration/temporal_test.cpp).
struct ShotMemory {
  int64_t from_pixels = std::numeric_limits<int64_t>::max();  // frames this large or larger
  int views_per_side = std::numeric_limits<int>::max();        // use at most these
  int temporal_per_side = std::numeric_limits<int>::max();
};

// Whether the request's frame is computed with its shot's neighbours (views or temporal).
bool in_shot(const FrameRequest& request) { return request.views_per_side > 0 || request.temporal_per_side > 0; }

// Why a frame of a shot was computed with fewer neighbours than asked (`used`, not `asked`).
std::string window_note(const FrameRequest& asked, const FrameRequest& used, int64_t limit_mb) {
  const std::string limit = limit_mb > 0 ? "the worker's limit of " + std::to_string(limit_mb) +
                                               " MiB (raise --memory-limit, or lower --views and --temporal)"
                                         : "the worker could allocate (lower --views and --temporal)";
  if (!in_shot(used))
    return "computed alone (no views, no temporal filtering): with its shot's neighbours the frame needs more "
           "memory than " + limit;
  return "computed with fewer neighbours (--views " + std::to_string(used.views_per_side) + " --temporal " +
         std::to_string(used.temporal_per_side) + " instead of " + std::to_string(asked.views_per_side) + " and " +
         std::to_string(asked.temporal_per_side) +
         "): with more of its shot's neighbours the frame needs more memory than " + limit;
}

// A frame computed within the worker's memory, and the window it was computed with.
struct FittedFrame {
  FrameResult result;
  int views_per_side = 0, temporal_per_side = 0;
  std::string window_note;  // empty when the window is the one asked for
};

// process_frame of `used`, its output's header saying which neighbours its window held
// (kWindowAttribute).
FrameResult process_with_window(FrameRequest& used, SequenceContext& context) {
  std::vector<std::pair<std::string, std::string>>& attributes = used.write.string_attributes;
  std::erase_if(attributes, [](const auto& a) { return a.first == kWindowAttribute; });
  attributes.push_back(
      {kWindowAttribute, window_attribute(used.neighbours, used.views_per_side, used.temporal_per_side)});
  return process_frame(used, &context);
}

// process_frame with the request's shot context, its window halved while the frame runs out
// of memory with it (ShotMemory); `pixels`: the frame's (frame_pixels). The context is
// emptied before each smaller window: its frames are what filled the memory.
FittedFrame process_frame_within_memory(const FrameRequest& request, int64_t pixels, SequenceContext& context,
                                        const WorkerArgs& args, ShotMemory& shot_memory) {
  FrameRequest used = request;
  if (pixels >= shot_memory.from_pixels) {
    used.views_per_side = std::min(used.views_per_side, shot_memory.views_per_side);
    used.temporal_per_side = std::min(used.temporal_per_side, shot_memory.temporal_per_side);
  }
  FittedFrame f;
  f.result = process_with_window(used, context);
  // A thread that cannot start ran out of the same address space (its stack, under
  // RLIMIT_AS) as an allocation that fails: either may fit once the context is emptied.
  while (!f.result.ok() && in_shot(used) && f.result.exhausted != ResourceFailure::none) {
    context.clear();
    // Freed, the context's memory serves the heap's next allocations but still holds its
    // address space (keep_freed_memory_for_reuse), which a thread's stack needs: unmapped.
    return_free_memory();
    used.views_per_side /= 2;
    used.temporal_per_side /= 2;
    shot_memory.from_pixels = std::min(shot_memory.from_pixels, pixels);
    shot_memory.views_per_side = std::min(shot_memory.views_per_side, used.views_per_side);
    shot_memory.temporal_per_side = std::min(shot_memory.temporal_per_side, used.temporal_per_side);
    f.result = process_with_window(used, context);
  }
  f.views_per_side = used.views_per_side;
  f.temporal_per_side = used.temporal_per_side;
  const bool reduced =
      used.views_per_side != request.views_per_side || used.temporal_per_side != request.temporal_per_side;
  if (f.result.ok() && reduced) f.window_note = window_note(request, used, args.memory_limit_mb);
  return f;
}

// The frame request of a job's options, its environment opened confined. Its outputs
// record the options as given: the environment's path, not the name of the descriptor it
// is read through (a rerun compares them, and --config takes them back).
bool resolve_request(const nlohmann::json& options_json, const Confinement& confine, JobFiles& files,
                     FrameRequest& request, std::string& error) {
  FrameOptionArgs options;
  if (!apply_json(options_json, options, error)) return false;
  const std::vector<std::pair<std::string, std::string>> attributes = output_attributes(options);
  if (!files.open_environment(confine, options.compute.env_path, error) ||
      !resolve_frame_options(options, request, error))
    return false;
  request.write.string_attributes = attributes;
  return true;
}

// Resolves the request's options (cached per option set) and computes its frame, every
// file opened confined by the worker (service/job_files.h).
void handle_request(const nlohmann::json& j, const WorkerArgs& args, std::map<std::string, FrameRequest>& resolved,
                    SequenceContext& sequence, RawTermsStore& raw_store, ShotMemory& shot_memory,
                    nlohmann::json& response) {
  const Confinement confine = Confinement::from_json(j.value("confine", nlohmann::json::object()));
  JobFiles files;
  const nlohmann::json options_json = j.value("options", nlohmann::json::object());
  // The cache key holds the roots too: a set resolved for one client's roots is not another's.
  const std::string options_key = options_json.dump() + confine.to_json().dump();
  auto it = resolved.find(options_key);
  std::string error;
  if (it == resolved.end()) {
    FrameRequest request;
    if (resolve_request(options_json, confine, files, request, error)) {
      if (resolved.size() >= kMaxCachedOptionSets) resolved.clear();
      it = resolved.emplace(options_key, std::move(request)).first;
    }
  }
  if (it == resolved.end()) {
    response["error"] = "options: " + files.named(error);
    return;
  }
  FrameRequest request = it->second;
  request.input_path = j["input"].get<std::string>();
  request.output_path = j.value("output", std::string());
  request.threads = args.threads;
  request.read.threads = args.threads;
  request.read.max_pixels = args.max_pixels;
  request.neighbours = neighbours_of(j);
  const bool camera_for_all = !request.read.camera_json.empty();  // --camera, not a sidecar
  if (!files.open(confine, request, error)) {
    response["error"] = error;
    return;
  }
  // A confined request's neighbours are opened like its input, and read through a context of
  // its own: descriptor names are this request's only. The raw terms its temporal filter
  // computes are kept across requests by the files' versions (RawTermsStore).
  std::vector<std::string> view_notes;
  SequenceContext confined;
  const bool is_confined = !confine.input_roots.empty();
  if (is_confined) files.open_neighbours(confine, request.neighbours, view_notes);
  if (camera_for_all) give_neighbours_camera(request.neighbours, request.read.camera_json);
  confined.share_raw_terms(&raw_store);
  // The headers, read once before decoding, for the memory estimate and a shot's fallback.
  ExrHeaderCheck headers;
  if (args.memory_limit_mb > 0 || in_shot(request)) {
    ExrLimits limits;
    limits.max_pixels = args.max_pixels;
    headers = check_exr_headers(request.input_path, limits);
  }
  FrameResult r;
  r.error = memory_estimate_refusal(request.input_path, headers, args.memory_limit_mb);
  // Raw terms kept for temporal filtering are of these options.
  sequence.use_settings(options_key);
  confined.use_settings(options_key);
  FittedFrame fitted;
  fitted.views_per_side = request.views_per_side;
  fitted.temporal_per_side = request.temporal_per_side;
  if (r.error.empty()) {
    fitted = process_frame_within_memory(request, frame_pixels(headers), is_confined ? confined : sequence, args,
                                         shot_memory);
    r = std::move(fitted.result);
  }
  if (!r.ok()) raw_store.clear();  // a failure (out of memory?) frees what the next frame may need
  r.info.notes.insert(r.info.notes.begin(), view_notes.begin(), view_notes.end());
  for (std::string& note : r.info.notes) note = files.named(note);
  response["ok"] = r.ok();
  if (!r.ok()) response["error"] = files.named(describe_memory_error(r.error, r.exhausted, args.memory_limit_mb));
  // The same frame may succeed in a new worker (service/worker_process.h, transient), with
  // its memory and its threads' stacks.
  if (r.exhausted != ResourceFailure::none) response["out_of_memory"] = true;
  response["read_ms"] = r.times.read_ms;
  response["compute_ms"] = r.times.compute_ms;
  response["write_ms"] = r.times.write_ms;
  response["terms"] = r.terms_written;
  response["width"] = r.info.width_px;
  response["height"] = r.info.height_px;
  response["notes"] = r.info.notes;
  // The shot's window the frame was computed with; a note when it is smaller than asked
  // (service/worker_process.h, WorkerResult).
  response["window"] = {{"views", fitted.views_per_side},
                        {"temporal", fitted.temporal_per_side},
                        {"note", files.named(fitted.window_note)}};
}

}  // namespace

int run_worker(const WorkerArgs& args) {
  // Die with the parent; and if it is gone already, do not start.
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (args.parent_pid > 0 && ::getppid() != pid_t(args.parent_pid)) return 0;
  // The parent decides when a worker ends (pipe closed, or SIGKILL); a terminal's Ctrl-C
  // a farm's SIGTERM or a closed terminal's SIGHUP to the process group goes to the
  // parent, which finishes the frames in flight.
  ::signal(SIGINT, SIG_IGN);
  ::signal(SIGTERM, SIG_IGN);
  ::signal(SIGHUP, SIG_IGN);
  ::signal(SIGPIPE, SIG_IGN);
  const rlimit no_core{0, 0};
  ::setrlimit(RLIMIT_CORE, &no_core);
  // Before any pool thread allocates (core/heap_policy.h); an idle worker hands the memory
  // back (kIdleTrimSeconds below).
  keep_freed_memory_for_reuse();
  // One thread budget for every pool in the worker: OpenCV's (the kernels and the reader's
  // conversions) and OpenEXR's (decoding and compression; one thread = in the calling
  // thread, no pool). Their threads are started before the address-space limit: their
  // stacks are not a frame's. OpenImageIO (environment maps other than EXR)
  // is loaded only if a request needs it (formats/oiio_module.h), possibly under the limit,
  // so it gets no pool: its work here is small, and a pool thread that cannot allocate as
  // it starts would end the worker.
  apply_thread_budget(args.threads);
  oiio_module::set_threads(1);
  g_response_fd = args.response_fd;
  g_memory_limit_mb = args.memory_limit_mb;
  std::set_terminate(terminate_with_last_words);
  if (args.memory_limit_mb > 0 && kMemoryLimitEnforced) {  // service/build_features.h
    start_pool_threads(args.threads, deadline_in(2.0));
    g_last_words_reserve = ::malloc(kLastWordsReserveBytes);
    const rlim_t bytes = rlim_t(args.memory_limit_mb) << 20;
    const rlimit as{bytes, bytes};
    ::setrlimit(RLIMIT_AS, &as);
  }

  std::map<std::string, FrameRequest> resolved;  // options JSON -> request template
  SequenceContext sequence;  // the shot's frames read so far, for the extra views
  RawTermsStore raw_store;   // raw terms of confined requests' frames, for the next requests
  ShotMemory shot_memory;    // from which size on a shot's frames are computed with a smaller window
  for (bool first = true;; first = false) {
    // After a frame, a worker idle for kIdleTrimSeconds returns its free memory, then waits.
    if (!first && !request_within(args.request_fd, kIdleTrimSeconds)) return_free_memory();
    std::string message;
    const IoStatus s = read_message(args.request_fd, message, kMaxRequestBytes, no_deadline());
    if (s != IoStatus::ok) return s == IoStatus::closed ? 0 : 1;
    const auto received = Clock::now();
    rusage usage{};
    const long faults_before = ::getrusage(RUSAGE_SELF, &usage) == 0 ? usage.ru_minflt + usage.ru_majflt : 0;
    nlohmann::json response{{"ok", false}};
    const nlohmann::json j = nlohmann::json::parse(message, nullptr, false);
    if (j.is_discarded() || !j.is_object() || !j.contains("input") || !j["input"].is_string()) {
      response["error"] = "malformed worker request";
    } else {
      handle_request(j, args, resolved, sequence, raw_store, shot_memory, response);
    }
    // Everything the worker spent on this request: the parent's wall time minus this is
    // the cost of isolation (pipes, scheduling).
    response["handled_ms"] = std::chrono::duration<double, std::milli>(Clock::now() - received).count();
    // Peak resident memory (the batch does not wait for its workers to exit, so its own
    // rusage does not include theirs), and the page faults of this request: the first
    // touches of fresh memory, dear on a virtual machine (core/heap_policy.h).
    if (::getrusage(RUSAGE_SELF, &usage) == 0) {
      response["peak_rss_mib"] = double(usage.ru_maxrss) / 1024.0;
      response["page_faults"] = std::max(0L, usage.ru_minflt + usage.ru_majflt - faults_before);
    }
    if (write_message(args.response_fd, to_wire(response), no_deadline()) != IoStatus::ok) return 1;
  }
}

Command register_worker(CLI::App& app) {
  auto worker = std::make_shared<WorkerArgs>();
  CLI::App* cmd = app.add_subcommand("worker", "Internal: a frame worker process")->group("");
  cmd->add_option("--threads", worker->threads)->check(CLI::Range(1, 1024));
  cmd->add_option("--memory-limit", worker->memory_limit_mb);
  cmd->add_option("--max-pixels", worker->max_pixels);
  cmd->add_option("--parent", worker->parent_pid);
  return {cmd, [worker] { return run_worker(*worker); }};
}

}  // namespace ssdo
