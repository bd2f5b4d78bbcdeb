// `ssdo bench`: every method x preset (and a sweep of sample counts) on frames with a
// reference pass: a CSV of time and error and a chart of error against time.
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>

#include <CLI/CLI.hpp>

#include "core/heap_policy.h"
#include "formats/chart.h"
#include "formats/input_file.h"
#include "formats/output_writer.h"
#include "kernels/metrics.h"
#include "service/cli_options.h"
#include "service/commands.h"
#include "service/comparison.h"
#include "service/parallelism.h"
#include "service/frame_inputs.h"
#include "service/frame_list.h"
#include "service/sequence.h"
#include "service/sequence_context.h"

namespace ssdo {

namespace {

struct BenchConfig {
  std::string preset;  // "low".."ultra" or "sweep"
  AoSettings settings;
};

// Depth taps per output pixel: the cost measure the sweep varies.
int taps_per_pixel(const AoSettings& s) {
  int taps = 0;
  switch (s.method) {
    case AoMethod::hemisphere: taps = s.samples; break;
    case AoMethod::hbao: taps = s.directions * s.steps; break;
    case AoMethod::gtao: taps = 2 * s.directions * s.steps; break;
    case AoMethod::raymarch: taps = s.directions * s.steps; break;
  }
  return std::max(1, taps / (s.resolution_divisor * s.resolution_divisor));
}

std::vector<BenchConfig> bench_configs(const std::vector<AoMethod>& methods, bool sweep) {
  std::vector<BenchConfig> configs;
  for (AoMethod m : methods) {
    for (Preset p : {Preset::low, Preset::medium, Preset::high, Preset::ultra}) {
      if (m == AoMethod::raymarch && p > Preset::medium) continue;  // minutes per frame
      configs.push_back({std::string(to_string(p)), ao_preset(m, p)});
    }
    if (!sweep) continue;
    // Full-resolution sweeps of the sample count around the presets.
    AoSettings s = ao_preset(m, Preset::high);
    s.resolution_divisor = 1;
    if (m == AoMethod::hemisphere) {
      for (int n : {4, 8, 16, 32, 64, 128}) { s.samples = n; configs.push_back({"sweep", s}); }
    } else if (m == AoMethod::hbao) {
      for (int n : {2, 4, 8, 16}) { s.directions = n; s.steps = 8; configs.push_back({"sweep", s}); }
    } else if (m == AoMethod::gtao) {
      for (int n : {1, 2, 4, 8}) { s.directions = n; s.steps = 8; configs.push_back({"sweep", s}); }
    }
  }
  return configs;
}

// The chart's colours (formats/chart.h palette): one per method, its presets, sample sweep
// and temporal variant told apart by their line; the external series in the colours left.
int chart_colour(AoMethod m) {
  switch (m) {
    case AoMethod::hemisphere: return 2;
    case AoMethod::hbao: return 3;
    case AoMethod::gtao: return 0;
    case AoMethod::raymarch: return 5;
  }
  return 7;
}
constexpr int kExternalColours[] = {7, 1, 4, 6};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Row {
  std::string file, method, preset, resolution;
  int samples = 0;
  double ms = 0;
  ErrorStats error;
};

// A CSV field (RFC 4180): quoted, with its quotes doubled, when it holds a comma, a quote
// or a line break (a file name may hold any of them).
std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

void write_csv_row(std::ostream& out, const Row& r) {
  out << csv_field(r.file) << ',' << r.method << ',' << r.preset << ',' << r.samples << ',' << r.resolution
      << ',' << r.ms << ',' << r.error.mae << ',' << r.error.rmse << ',' << r.error.bias << ','
      << r.error.p95 << '\n';
}

// External reference costs: CSV "series,label,ms,mae" (header line optional).
bool read_external(const std::string& path, std::vector<ChartSeries>& series, std::string& error) {
  if (error = input_file_error(path, "external reference CSV", kMaxTextFileBytes); !error.empty()) return false;
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open the external reference CSV";
    return false;
  }
  std::map<std::string, size_t> index;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    std::stringstream ss(line);
    std::string name, label, ms, mae;
    if (!std::getline(ss, name, ',') || !std::getline(ss, label, ',') || !std::getline(ss, ms, ',') ||
        !std::getline(ss, mae, ',')) {
      error = path + ":" + std::to_string(line_no) + ": expected series,label,ms,mae";
      return false;
    }
    // The whole field a number (no "12ms"), a time > 0 and an error >= 0, both finite: the
    // chart's axes are logarithmic in time and linear in error.
    auto number = [](const std::string& text, double& value) {
      const size_t first = text.find_first_not_of(" \t"), last = text.find_last_not_of(" \t\r");
      if (first == std::string::npos) return false;
      const char* end = text.data() + last + 1;
      const auto [stop, ec] = std::from_chars(text.data() + first, end, value);
      return ec == std::errc() && stop == end && std::isfinite(value);
    };
    double ms_v = 0, mae_v = 0;
    if (!number(ms, ms_v) || !number(mae, mae_v)) {
      if (line_no == 1) continue;  // header
      error = path + ":" + std::to_string(line_no) + ": ms and mae must be numbers";
      return false;
    }
    if (!(ms_v > 0) || !(mae_v >= 0)) {
      error = path + ":" + std::to_string(line_no) + ": ms must be above 0 and mae at least 0";
      return false;
    }
    if (!index.count(name)) {
      index[name] = series.size();
      const int colour = kExternalColours[series.size() % std::size(kExternalColours)];
      series.push_back({name + " (external)", {}, true, colour, ChartLine::solid});
    }
    series[index[name]].points.push_back({ms_v, mae_v, label});
  }
  return true;
}

// A frame to measure: its G-buffer, reference and radius.
struct Loaded {
  std::string path;
  GBuffer g;
  cv::Mat reference;
  float radius = 1;
};

// The row name of a preset computed as a shot: "medium+v2+t2" for --views 2 --temporal 2.
std::string sequence_variant(const std::string& preset, const BenchArgs& args) {
  return preset + (args.views > 0 ? "+v" + std::to_string(args.views) : "") +
         (args.temporal > 0 ? "+t" + std::to_string(args.temporal) : "");
}

// A preset over the sequences among the frames as a batch computes them (the sequence
// context, as `ssdo eval` does): with --views K each frame uses up to K neighbours on each
// side as extra views, with --temporal K its denoised terms are filtered over the raw terms
// of K frames on each side, and each frame's raw terms are computed once. A frame's ms: its
// compute (its raw terms, those of the neighbours it is the first to need, its finish; not
// the reads), the median over `runs` runs of the whole sequence, each in a fresh context.
// Writes a CSV row per frame and returns the row over all.
Row bench_sequence(const std::vector<Loaded>& frames, const BenchArgs& args, const BenchConfig& config,
                   std::ostream& csv) {
  std::vector<std::string> paths;
  for (const Loaded& f : frames) paths.push_back(f.path);
  const auto lists = sequence_neighbours(paths, neighbour_places(args.views, args.temporal));
  FrameRequest request = args.request;
  request.terms = {true, false, false};
  request.ao = config.settings;
  request.views_per_side = args.views;
  request.temporal_per_side = args.temporal;
  const ReadOptions read = reads_for(request);
  std::vector<std::vector<double>> times(frames.size());
  std::vector<cv::Mat> estimates(frames.size());
  for (int run = 0; run < args.runs; ++run) {
    SequenceContext sequence;
    for (size_t i = 0; i < frames.size(); ++i) {
      FrameRequest r = request;
      r.input_path = paths[i];
      r.neighbours = lists[i];
      for (NeighbourFrame& n : r.neighbours)  // later in the files, whatever its number
        n.computed_later = size_t(std::find(paths.begin(), paths.end(), n.path) - paths.begin()) > i;
      give_neighbours_camera(r.neighbours, r.read.camera_json);
      ReadResult f = sequence.read(r, read);
      std::string error;
      if (!f.ok() || !resolve_frame_radius(r, f.info, error)) continue;  // read and resolved once before
      std::vector<std::string> notes;
      const auto t0 = std::chrono::steady_clock::now();
      const ComputedFrame computed = sequence.compute(r, read, std::move(f.gbuffer), notes);
      times[i].push_back(ms_since(t0));
      estimates[i] = *computed.find(output_term_name(OutputTermId::ao_denoised));
    }
  }
  Row all{"all", std::string(to_string(config.settings.method)), sequence_variant(config.preset, args), "",
          taps_per_pixel(config.settings), 0, {}};
  ErrorAccumulator overall;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (estimates[i].empty()) continue;
    Row r = all;
    r.file = frames[i].path;
    r.resolution = std::to_string(frames[i].g.width_px()) + "x" + std::to_string(frames[i].g.height_px());
    r.ms = median(times[i]);
    r.error = compare_images(estimates[i], frames[i].reference, frames[i].g.mask);
    write_csv_row(csv, r);
    overall.add(estimates[i], frames[i].reference, frames[i].g.mask);
    all.ms += r.ms / double(frames.size());
    all.resolution = all.resolution.empty() || all.resolution == r.resolution ? r.resolution : "mixed";
  }
  all.error = overall.result();
  write_csv_row(csv, all);
  return all;
}

}  // namespace

int run_bench(const BenchArgs& args) {
  // Frames are computed in this process: the heap and the threads as in a worker.
  keep_freed_memory_for_reuse();
  apply_thread_budget(args.request.threads);
  std::error_code ec;
  std::filesystem::create_directories(args.output_dir, ec);
  if (ec) {
    std::cerr << "ssdo bench: cannot create " << args.output_dir << ": " << ec.message() << "\n";
    return 2;
  }
  // A folder where a table or the chart goes would fail the run after every frame was
  // measured: refused before.
  for (const char* name : {"bench.csv", "calibration.csv", "bench.png"})
    if (std::filesystem::is_directory(std::filesystem::path(args.output_dir) / name, ec)) {
      std::cerr << "ssdo bench: " << (std::filesystem::path(args.output_dir) / name).string()
                << " is a folder: the run writes a file by that name\n";
      return 2;
    }
  std::vector<ChartSeries> external;
  std::string error;
  if (!args.external_csv.empty() && !read_external(args.external_csv, external, error)) {
    std::cerr << "ssdo bench: " << error << "\n";
    return 2;
  }

  // Read every frame once.
  std::vector<Loaded> frames;
  int failed = 0;
  for (const std::string& file : args.files) {
    ReadOptions read = args.request.read;
    read.read_references = true;
    ReadResult r = read_frame(file, read);
    if (!r.ok()) {
      std::cerr << "ssdo bench: " << r.error << "\n";
      ++failed;
      continue;
    }
    auto it = r.gbuffer.references.find(args.reference);
    if (it == r.gbuffer.references.end()) {
      std::cerr << "ssdo bench: " << file << ": no reference pass '" << args.reference << "'\n";
      ++failed;
      continue;
    }
    cv::Mat ref = it->second;
    if (ref.channels() == 3) cv::transform(ref, ref, cv::Matx<float, 1, 3>(1.0f / 3, 1.0f / 3, 1.0f / 3));
    // The pixels any estimate can be compared on: the foreground where the reference is
    // finite. A frame without one is no measurement, as in `ssdo eval`.
    const int64_t comparable = compare_images(ref, ref, r.gbuffer.mask).pixels;
    if (const std::string reason = no_comparison_reason(comparable, r.info.foreground_pixels); !reason.empty()) {
      std::cerr << "ssdo bench: " << file << ": " << reason << "\n";
      ++failed;
      continue;
    }
    if (const std::string note = left_out_note(comparable, r.info.foreground_pixels); !note.empty())
      std::cerr << "ssdo bench: " << file << ": " << note << "\n";
    frames.push_back({file, std::move(r.gbuffer), ref, resolve_radius_world(args.request.radius_given_world, r.info)});
  }
  if (frames.empty()) {
    std::cerr << "ssdo bench: no frame with a reference to measure\n";
    return 1;
  }

  // The tables are written when complete, each through a temporary file (complete or
  // absent, as the frames' outputs), and a failure to write one fails the run.
  std::ostringstream csv, calibration;
  csv << "file,method,preset,samples,resolution,ms,mae,rmse,bias,p95\n";
  calibration << "method,preset,samples,ms,mae\n";
  std::map<std::string, ChartSeries> by_method;
  std::printf("%-10s %-7s %7s %10s %8s %8s %8s\n", "method", "preset", "samples", "ms", "MAE", "RMSE", "p95");

  for (const BenchConfig& config : bench_configs(args.methods, args.sweep)) {
    ErrorAccumulator overall;
    double ms_sum = 0;
    std::string resolution;
    Row row;
    row.method = std::string(to_string(config.settings.method));
    row.preset = config.preset;
    row.samples = taps_per_pixel(config.settings);
    for (const Loaded& f : frames) {
      FrameRequest request = args.request;
      request.terms = {true, false, false};
      request.ao = config.settings;
      request.ao.radius_world = f.radius;
      std::vector<double> times;
      ComputedFrame computed;
      for (int run = 0; run < args.runs; ++run) {
        const auto t0 = std::chrono::steady_clock::now();
        computed = compute_frame(f.g, request);
        times.push_back(ms_since(t0));
      }
      const cv::Mat& ao = *computed.find(output_term_name(OutputTermId::ao_denoised));
      Row r = row;
      r.file = f.path;
      r.resolution = std::to_string(f.g.width_px()) + "x" + std::to_string(f.g.height_px());
      r.ms = median(times);
      r.error = compare_images(ao, f.reference, f.g.mask);
      write_csv_row(csv, r);
      overall.add(ao, f.reference, f.g.mask);
      ms_sum += r.ms;
      resolution = resolution.empty() || resolution == r.resolution ? r.resolution : "mixed";
    }
    row.file = "all";
    row.resolution = resolution;
    row.ms = ms_sum / double(frames.size());
    row.error = overall.result();
    write_csv_row(csv, row);
    if (config.preset != "sweep")
      calibration << row.method << ',' << row.preset << ',' << row.samples << ',' << row.ms << ','
                  << row.error.mae << '\n';
    std::printf("%-10s %-7s %7d %10.1f %8.4f %8.4f %8.4f\n", row.method.c_str(), row.preset.c_str(),
                row.samples, row.ms, row.error.mae, row.error.rmse, row.error.p95);
    std::fflush(stdout);
    // Presets and the sample sweep are separate curves of the method.
    const std::string series_name = row.method + (config.preset == "sweep" ? " samples" : " presets");
    ChartSeries& s = by_method[series_name];
    s.name = series_name;
    s.colour = chart_colour(config.settings.method);
    s.line = config.preset == "sweep" ? ChartLine::thin : ChartLine::solid;
    s.points.push_back({row.ms, row.error.mae, config.preset == "sweep" ? std::to_string(row.samples) : config.preset});
    if ((args.temporal <= 0 && args.views <= 0) || config.preset == "sweep") continue;
    const Row t = bench_sequence(frames, args, config, csv);
    std::printf("%-10s %-7s %7d %10.1f %8.4f %8.4f %8.4f\n", t.method.c_str(), t.preset.c_str(), t.samples, t.ms,
                t.error.mae, t.error.rmse, t.error.p95);
    const std::string sequence_name = row.method + "," +
                                      (args.views > 0 ? " --views " + std::to_string(args.views) : "") +
                                      (args.temporal > 0 ? " --temporal " + std::to_string(args.temporal) : "");
    ChartSeries& ts = by_method[sequence_name];
    ts.name = sequence_name;
    ts.colour = chart_colour(config.settings.method);
    ts.line = ChartLine::dashed;
    ts.points.push_back({t.ms, t.error.mae, config.preset});
  }

  std::vector<ChartSeries> series;
  for (auto& [name, s] : by_method) series.push_back(s);
  series.insert(series.end(), external.begin(), external.end());
  ChartOptions chart;
  chart.title = "AO error against time per frame (" + std::to_string(frames.size()) + " frame" +
                (frames.size() > 1 ? "s" : "") + ", reference " + args.reference + ")";
  chart.y_label = "MAE against " + args.reference + " (AO units, 0..1)";
  const std::filesystem::path out(args.output_dir);
  const std::string png = (out / "bench.png").string();
  bool written = true;
  for (const std::string& e : {write_file_atomically(out / "bench.csv", csv.str()),
                               write_file_atomically(out / "calibration.csv", calibration.str()),
                               write_chart_png(png, series, chart)})
    if (!e.empty()) {
      std::cerr << "ssdo bench: " << e << "\n";
      written = false;
    }
  if (!written) return 1;
  std::printf("wrote %s/bench.csv, %s/calibration.csv and %s\n", args.output_dir.c_str(),
              args.output_dir.c_str(), png.c_str());
  return failed ? 1 : 0;
}

Command register_bench(CLI::App& app) {
  struct State {
    BenchArgs bench;
    FrameOptionArgs options;
    std::vector<std::string> methods;
    bool no_sweep = false;
  };
  auto st = std::make_shared<State>();
  BenchArgs& b = st->bench;
  CLI::App* cmd = app.add_subcommand(
      "bench", "Run every AO method x preset (and a sweep of sample counts) on frames with a "
               "reference pass; write bench.csv (method, preset, samples, resolution, median ms, "
               "MAE, RMSE, bias, p95), calibration.csv (for --quality auto) and bench.png (error "
               "against time, log time axis)");
  cmd->add_option("files", b.files, "EXR frames holding the reference pass")->required();
  cmd->add_option("--reference", b.reference, "Reference pass name")->capture_default_str();
  cmd->add_option("-o,--out", b.output_dir, "Output folder")->required();
  cmd->add_option("--runs", b.runs, "Runs per configuration (median time)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_option("--methods", st->methods,
                  "Methods to run (default hemisphere hbao gtao; raymarch is minutes per frame)")
      ->check(CLI::IsMember({"hemisphere", "hbao", "gtao", "raymarch"}));
  cmd->add_flag("--no-sweep", st->no_sweep, "Presets only, no sample-count sweep");
  cmd->add_option("--external", b.external_csv,
                  "CSV of an external reference's cost (series,label,ms,mae), e.g. a ray "
                  "tracer at several sample counts, plotted beside the methods")
      ->check(CLI::ExistingFile);
  cmd->add_option("--threads", b.request.threads, "Threads for the kernels (0 = all cores; at most the cores)")
      ->check(CLI::Range(0, 1024));
  cmd->add_option("--temporal", b.temporal,
                  "Also each preset computed as a shot, with --temporal K: the frames of a sequence among the files "
                  "(names that differ in a frame number) filtered over K frames each side, their time including the "
                  "raw terms (a row per preset 'PRESET+tK' and a curve on the chart)")
      ->check(CLI::Range(0, 8));
  cmd->add_option("--views", b.views,
                  "Also each preset computed as a shot, with --views K: each frame of a sequence among the files "
                  "uses up to K neighbours on each side as extra views (with --temporal too: 'PRESET+vK+tK'). The "
                  "rows of the presets alone are frames alone")
      ->check(CLI::Range(0, 8));
  add_frame_options(*cmd, st->options, int(OptionSet::read));
  return {cmd, [st] {
            BenchArgs& bench = st->bench;
            std::string error;
            if (!resolve_read_options(st->options.read, bench.request.read, error)) return usage_error(error);
            if (!st->methods.empty()) {
              bench.methods.clear();
              for (const std::string& m : st->methods)  // each method once, in the order first given
                if (std::find(bench.methods.begin(), bench.methods.end(), *parse_ao_method(m)) == bench.methods.end())
                  bench.methods.push_back(*parse_ao_method(m));
            }
            bench.sweep = !st->no_sweep;
            bench.request.threads = frame_threads(bench.request.threads);
            bench.files = each_file_once(bench.files);  // a file listed twice counts once
            return run_bench(bench);
          }};
}

}  // namespace ssdo
