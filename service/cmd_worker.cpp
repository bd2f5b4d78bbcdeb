// `ssdo worker` (hidden): the process that decodes and computes frames for the batch and
// the service (see service/worker_process.h). Reads requests from fd 3, answers on fd 4,
// exits when the request pipe closes.
#include <malloc.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <exception>
#include <map>
#include <string>

#include <OpenEXR/ImfThreading.h>
#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>

#include "service/build_features.h"
#include "service/protocol.h"
#include "service/request_options.h"
#include "service/worker_process.h"

namespace ssdo {

namespace {

constexpr size_t kMaxRequestBytes = size_t(1) << 20;
// Resolved option sets kept (the environment map is loaded once per set).
constexpr size_t kMaxCachedOptionSets = 8;

// The response descriptor, for the last words of a worker ending on an uncaught
// exception (std::terminate runs no destructors and has no arguments).
int g_response_fd = -1;

[[noreturn]] void terminate_with_last_words() {
  std::string what = "an unknown exception";
  if (const std::exception_ptr e = std::current_exception()) {
    try {
      std::rethrow_exception(e);
    } catch (const std::bad_alloc&) {
      what = "out of memory (std::bad_alloc)";
    } catch (const std::exception& ex) {
      what = ex.what();
    } catch (...) {
    }
  }
  const std::string message =
      to_wire(nlohmann::json{{"ok", false}, {"exiting", true}, {"error", "worker aborted: uncaught exception: " + what}});
  if (g_response_fd >= 0) write_message(g_response_fd, message, deadline_in(1.0));
  ::_exit(134);
}

std::string describe_memory_error(const std::string& error, int64_t limit_mb) {
  const bool no_memory = error.find("bad_alloc") != std::string::npos ||
                         error.find("Insufficient memory") != std::string::npos ||
                         error.find("out of memory") != std::string::npos;
  // Threads (OpenEXR's and OpenCV's pools) cannot get their stacks under RLIMIT_AS.
  const bool no_thread = error.find("Resource temporarily unavailable") != std::string::npos;
  if (!no_memory && !no_thread) return error;
  return error + (no_memory ? " (out of memory: the frame needs more than the worker's limit of "
                            : " (no memory for a thread under the worker's limit of ") +
         std::to_string(limit_mb) + " MiB, see --memory-limit)";
}

}  // namespace

int run_worker(const WorkerArgs& args) {
  // Die with the parent; and if it is gone already, do not start.
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (args.parent_pid > 0 && ::getppid() != pid_t(args.parent_pid)) return 0;
  // The parent decides when a worker ends (pipe closed, or SIGKILL); a terminal's Ctrl-C
  // or a farm's SIGTERM to the process group goes to the parent, which finishes the
  // frames in flight.
  ::signal(SIGINT, SIG_IGN);
  ::signal(SIGTERM, SIG_IGN);
  ::signal(SIGPIPE, SIG_IGN);
  const rlimit no_core{0, 0};
  ::setrlimit(RLIMIT_CORE, &no_core);
  // One thread budget for every pool in the worker: OpenCV's (the kernels and the reader's
  // conversions), OpenEXR's (decoding and compression; one thread = in the calling thread,
  // no pool) and OpenImageIO's (environment maps, PNG previews; OpenImageIO also resizes
  // OpenEXR's pool when it opens an EXR, so it is told the same size). Before the
  // address-space limit: OpenEXR starts its threads here, and their stacks are not a frame's.
  cv::setNumThreads(args.threads);
  Imf::setGlobalThreadCount(args.threads > 1 ? args.threads : 0);
  OIIO::attribute("threads", args.threads);
  OIIO::attribute("exr_threads", args.threads > 1 ? args.threads : -1);
  if (args.memory_limit_mb > 0 && kMemoryLimitEnforced) {  // service/build_features.h
    const rlim_t bytes = rlim_t(args.memory_limit_mb) << 20;
    const rlimit as{bytes, bytes};
    ::setrlimit(RLIMIT_AS, &as);
  }
  // Each malloc arena reserves 64 MiB of address space; one per thread would eat the
  // RLIMIT_AS budget without using memory.
  ::mallopt(M_ARENA_MAX, 2);
  g_response_fd = args.response_fd;
  std::set_terminate(terminate_with_last_words);

  std::map<std::string, FrameRequest> resolved;  // options JSON -> request template
  for (;;) {
    std::string message;
    const IoStatus s = read_message(args.request_fd, message, kMaxRequestBytes, no_deadline());
    if (s != IoStatus::ok) return s == IoStatus::closed ? 0 : 1;
    const auto received = Clock::now();
    nlohmann::json response{{"ok", false}};
    const nlohmann::json j = nlohmann::json::parse(message, nullptr, false);
    if (j.is_discarded() || !j.is_object() || !j.contains("input") || !j["input"].is_string()) {
      response["error"] = "malformed worker request";
    } else {
      const std::string options_key = j.value("options", nlohmann::json::object()).dump();
      auto it = resolved.find(options_key);
      std::string error;
      if (it == resolved.end()) {
        FrameOptionArgs options;
        FrameRequest request;
        if (apply_json(j.value("options", nlohmann::json::object()), options, error) &&
            resolve_frame_options(options, request, error)) {
          if (resolved.size() >= kMaxCachedOptionSets) resolved.clear();
          it = resolved.emplace(options_key, std::move(request)).first;
        }
      }
      if (it == resolved.end()) {
        response["error"] = "options: " + error;
      } else {
        FrameRequest request = it->second;
        request.input_path = j["input"].get<std::string>();
        request.output_path = j.value("output", std::string());
        request.threads = args.threads;
        request.read.threads = args.threads;
        request.read.max_pixels = args.max_pixels;
        const FrameResult r = process_frame(request);
        response["ok"] = r.ok();
        if (!r.ok()) response["error"] = describe_memory_error(r.error, args.memory_limit_mb);
        response["read_ms"] = r.times.read_ms;
        response["compute_ms"] = r.times.compute_ms;
        response["write_ms"] = r.times.write_ms;
        response["terms"] = r.terms_written;
        response["width"] = r.info.width_px;
        response["height"] = r.info.height_px;
      }
    }
    // Everything the worker spent on this request: the parent's wall time minus this is
    // the cost of isolation (pipes, scheduling).
    response["handled_ms"] = std::chrono::duration<double, std::milli>(Clock::now() - received).count();
    if (write_message(args.response_fd, to_wire(response), no_deadline()) != IoStatus::ok) return 1;
  }
}

}  // namespace ssdo
