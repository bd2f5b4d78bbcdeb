// `ssdo process`: a batch over frames. A bad frame is reported and the batch goes on;
// exit code 1 if any frame failed, 0 otherwise (2 for usage errors, before any work).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "service/commands.h"
#include "service/frame_list.h"
#include "service/frame_range.h"

namespace ssdo {

namespace {

// Inputs -> the ordered frame list of this batch (patterns expanded with --frames),
// then this chunk's slice of it.
bool collect_frames(const ProcessArgs& args, std::vector<std::string>& frames, std::string& error) {
  std::vector<int> numbers;
  if (!args.frames.empty() && !parse_frame_ranges(args.frames, numbers, error)) {
    error = "--frames: " + error;
    return false;
  }
  std::vector<std::string> plain;
  for (const std::string& input : args.inputs) {
    if (!has_frame_pattern(input)) {
      plain.push_back(input);
      continue;
    }
    if (numbers.empty()) {
      error = input + ": a frame pattern needs --frames, e.g. --frames 1-100";
      return false;
    }
    // Pattern frames are listed even when the file is missing: a missing frame of a
    // requested range is that frame's error, reported like any other.
    if (!expand_inputs(plain, frames, error)) return false;
    plain.clear();
    for (int n : numbers) frames.push_back(expand_frame_pattern(input, n));
  }
  if (!expand_inputs(plain, frames, error)) return false;
  if (!args.chunk.empty()) {
    int index = 0, count = 0;
    if (!parse_chunk(args.chunk, index, count, error)) return false;
    frames = chunk_slice(frames, index, count);
  }
  return true;
}

}  // namespace

int run_process(const ProcessArgs& args) {
  std::vector<std::string> frames;
  std::string error;
  if (!collect_frames(args, frames, error)) {
    std::cerr << "ssdo process: " << error << "\n";
    return 2;
  }
  if (frames.empty()) {
    std::cerr << "ssdo process: no frames to process (an empty folder or chunk)\n";
  }
  std::error_code ec;
  std::filesystem::create_directories(args.output_dir, ec);
  if (ec) {
    std::cerr << "ssdo process: cannot create output folder " << args.output_dir << ": "
              << ec.message() << "\n";
    return 2;
  }

  const auto t_start = std::chrono::steady_clock::now();
  int done = 0, skipped = 0, failed = 0;
  const int total = int(frames.size());
  for (int i = 0; i < total; ++i) {
    FrameRequest request = args.request;
    request.input_path = frames[i];
    request.output_path = output_path_for(frames[i], args.output_dir);
    char counter[48];
    std::snprintf(counter, sizeof counter, "[%d/%d] ", i + 1, total);
    if (!args.force && output_up_to_date(request.input_path, request.output_path)) {
      ++skipped;
      std::cout << counter << request.input_path << ": skipped (output up to date: "
                << request.output_path << ")\n" << std::flush;
      continue;
    }
    const FrameResult r = process_frame(request);
    const double elapsed_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    const int finished = done + failed + 1;
    const double fps = finished / std::max(elapsed_s, 1e-9);
    const double eta_s = (total - i - 1) / std::max(fps, 1e-9);
    if (r.ok()) {
      ++done;
      std::cout << counter << request.input_path << " -> " << r.output_path << ": ok";
    } else {
      ++failed;
      std::cout << counter << request.input_path << ": FAILED: " << r.error;
    }
    char rate[96];
    std::snprintf(rate, sizeof rate, " (%.0f ms; %.2f frames/s, ETA %.0f s)",
                  r.times.read_ms + r.times.compute_ms + r.times.write_ms, fps, eta_s);
    std::cout << rate;
    if (args.verbose) {
      char stages[128];
      std::snprintf(stages, sizeof stages, " read %.1f ms, compute %.1f ms, write %.1f ms",
                    r.times.read_ms, r.times.compute_ms, r.times.write_ms);
      std::cout << stages;
    }
    std::cout << "\n" << std::flush;
  }
  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  char summary[160];
  std::snprintf(summary, sizeof summary, "done %d, skipped %d, failed %d, %.2f s", done, skipped,
                failed, total_s);
  std::cout << summary << "\n";
  return failed > 0 ? 1 : 0;
}

}  // namespace ssdo
