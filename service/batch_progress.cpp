#include "service/batch_progress.h"

#include <algorithm>
#include <cstdio>
#include <iostream>

#include "formats/gbuffer_reader.h"
#include "service/protocol.h"

namespace ssdo {

double batch_frames_per_s(int computed, double elapsed_s, int workers, double mean_frame_ms) {
  const double measured = computed / std::max(elapsed_s, 1e-9);
  return mean_frame_ms > 0 ? std::max(measured, 1000.0 * workers / mean_frame_ms) : measured;
}

BatchProgress::BatchProgress(int total, int to_compute, int workers, bool bar, bool verbose)
    : total_(total), to_compute_(to_compute), workers_(std::max(workers, 1)), bar_(bar), verbose_(verbose) {}

double BatchProgress::elapsed_s() const {
  return std::chrono::duration<double>(Clock::now() - start_).count();
}

double BatchProgress::frames_per_s() const {
  return batch_frames_per_s(done_ + failed_, elapsed_s(), workers_, frames_ok_ ? frames_ok_ms_ / frames_ok_ : 0.0);
}

std::string BatchProgress::counter() {
  char s[48];
  std::snprintf(s, sizeof s, "[%d/%d] ", done_ + skipped_ + failed_, total_);
  return s;
}

void BatchProgress::draw_bar() {
  const int finished = done_ + skipped_ + failed_;
  const int computed = done_ + failed_;
  const double fps = frames_per_s();
  const int remaining = to_compute_ - computed;
  constexpr int kWidth = 30;
  const int filled = total_ > 0 ? kWidth * finished / total_ : kWidth;
  std::string bar(size_t(filled), '=');
  bar.resize(kWidth, ' ');
  char eta[32] = "--";
  if (computed > 0) {
    const int s = int(remaining / std::max(fps, 1e-9) + 0.5);
    std::snprintf(eta, sizeof eta, "%d:%02d", s / 60, s % 60);
  }
  char line[192];
  std::snprintf(line, sizeof line, "\r\033[K[%s] %d/%d  %.2f frames/s  ETA %s%s", bar.c_str(), finished, total_,
                fps, eta, failed_ ? ("  failed " + std::to_string(failed_)).c_str() : "");
  std::cerr << line << std::flush;
}

void BatchProgress::skipped(const std::string& input, const std::string& output) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++skipped_;
  if (bar_) {
    draw_bar();
    return;
  }
  std::cout << counter() << printable(input) << ": skipped (output up to date: " << printable(output) << ")\n"
            << std::flush;
}

void BatchProgress::finished(const std::string& input, const std::string& output, const WorkerResult& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  (r.ok() ? done_ : failed_) += 1;
  if (r.ok()) {  // a frame that fails may fail at once: not a frame's time
    frames_ok_ms_ += r.wall_ms;
    ++frames_ok_;
  }
  // Isolation = what the parent waited beyond the worker's own handling of the request.
  const double isolation_ms = std::max(0.0, r.wall_ms - r.handled_ms);
  if (r.ok() && r.worker_started) {
    startup_ms_ += isolation_ms;
    ++startups_;
  } else if (r.ok()) {
    isolation_ms_ += isolation_ms;
    ++warm_frames_;
  }
  const int computed = done_ + failed_;
  const double fps = frames_per_s();
  const double eta_s = (to_compute_ - computed) / std::max(fps, 1e-9);
  // One line per frame, whatever the names hold (control characters escaped).
  std::string line = counter() + printable(input);
  line += r.ok() ? " -> " + printable(output) + ": ok" : ": FAILED: " + printable(r.error);
  char rate[96];
  std::snprintf(rate, sizeof rate, " (%.0f ms; %.2f frames/s, ETA %.0f s)", r.wall_ms, fps, eta_s);
  line += rate;
  if (verbose_) {
    char stages[224];
    std::snprintf(stages, sizeof stages,
                  " read %.1f ms, compute %.1f ms, write %.1f ms, worker %.1f ms, isolation %.2f ms, worker peak RSS "
                  "%.0f MiB, %d page faults",
                  r.times.read_ms, r.times.compute_ms, r.times.write_ms, r.handled_ms,
                  std::max(0.0, r.wall_ms - r.handled_ms), r.peak_rss_mib, r.page_faults);
    line += stages;
  }
  // Notes are -v's, but warnings (FrameInfo::notes) and the one of a smaller window, which
  // change the frame's terms, are shown always.
  bool warned = false;
  for (const std::string& note : r.notes) {
    const bool warning = note.rfind(kWarningNote, 0) == 0;
    warned |= warning;
    if (verbose_ || warning) line += "\n  note: " + printable(note);
  }
  const bool changed_terms = r.ok() && r.window_reduced();
  if (changed_terms) line += "\n  note: " + r.window_note;
  for (const std::string& warning : r.warnings) line += "\n  note: " + printable(warning);
  if (!bar_) {
    std::cout << line << "\n" << std::flush;
    return;
  }
  if (!r.ok() || verbose_ || changed_terms || warned || !r.warnings.empty()) std::cerr << "\r\033[K" << line << "\n";
  draw_bar();
}

int BatchProgress::summary(bool interrupted) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bar_) std::cerr << "\r\033[K" << std::flush;
  char s[256];
  std::snprintf(s, sizeof s, "done %d, skipped %d, failed %d, %.2f s", done_, skipped_, failed_, elapsed_s());
  std::cout << s;
  if (interrupted)
    std::cout << "; interrupted: " << (total_ - done_ - skipped_ - failed_) << " frames not started";
  if (verbose_ && warm_frames_ > 0) {
    std::snprintf(s, sizeof s, "; isolation %.2f ms per frame", isolation_ms_ / warm_frames_);
    std::cout << s;
  }
  if (verbose_ && startups_ > 0) {
    std::snprintf(s, sizeof s, " (+ %.0f ms per worker start, %d starts)", startup_ms_ / startups_, startups_);
    std::cout << s;
  }
  std::cout << "\n" << std::flush;
  return failed_;
}

}  // namespace ssdo
