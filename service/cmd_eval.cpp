// `ssdo eval`: AO against a reference pass of the same frame, over foreground pixels.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "core/heap_policy.h"
#include "kernels/metrics.h"
#include "service/cli_options.h"
#include "service/commands.h"
#include "service/comparison.h"
#include "service/parallelism.h"
#include "service/frame_inputs.h"
#include "service/frame_list.h"
#include "service/sequence.h"
#include "service/sequence_context.h"
#include "service/view_selection.h"

namespace ssdo {

namespace {

// The channel mean of each pixel, in float (terms kept in half are read as they are).
cv::Mat to_single_channel(const cv::Mat& m) {
  cv::Mat values = m;
  if (m.depth() != CV_32F) m.convertTo(values, CV_32F);
  if (values.channels() == 1) return values;
  cv::Mat out;
  cv::transform(values, out, cv::Matx<float, 1, 3>(1.0f / 3, 1.0f / 3, 1.0f / 3));
  return out;
}

// Signed error as colour: red where the estimate is too open (bright), blue where it is
// too dark; full intensity at |error| >= 0.25. Background, and pixels not compared (a
// non-finite reference), black.
cv::Mat error_heatmap(const cv::Mat& estimate, const cv::Mat& reference, const cv::Mat& mask) {
  cv::Mat heat(estimate.size(), CV_32FC3, cv::Scalar::all(0));
  for (int y = 0; y < estimate.rows; ++y)
    for (int x = 0; x < estimate.cols; ++x) {
      const float difference = estimate.at<float>(y, x) - reference.at<float>(y, x);
      if (!mask.at<uint8_t>(y, x) || !std::isfinite(difference)) continue;  // as compare_images: not compared
      const float e = std::clamp(difference * 4.0f, -1.0f, 1.0f);
      heat.at<cv::Vec3f>(y, x) = e > 0 ? cv::Vec3f(e, 0, 0) : cv::Vec3f(0, 0, -e);
    }
  return heat;
}

// The term computed by the screen-space oracle with the request's radius and thickness (its
// model too: the estimate from silhouettes when the request's AO makes one).
cv::Mat oracle_term(const GBuffer& g, const FrameRequest& request, const std::string& term,
                    const std::string& preset_name) {
  const Preset preset = parse_preset(preset_name).value_or(Preset::medium);
  FrameRequest oracle = request;
  if (term == "ao") {
    oracle.ao = ao_preset(AoMethod::raymarch, preset);
    oracle.ao.radius_world = request.ao.radius_world;
    oracle.ao.thickness_world = effective_thickness_world(request.ao);
    oracle.ao.thickness_model =
        estimates_back_layer(request.ao) ? ThicknessModel::silhouettes : ThicknessModel::constant;
    oracle.ao.silhouettes = request.ao.silhouettes;
    oracle.ao.depth_bias_relative = request.ao.depth_bias_relative;
  } else {
    oracle.ssdo = ssdo_preset(SsdoMethod::oracle, preset);
    oracle.ssdo.radius_world = request.ssdo.radius_world;
    oracle.ssdo.thickness_world = request.ssdo.thickness_world;
    oracle.ssdo.depth_bias_relative = request.ssdo.depth_bias_relative;
  }
  const ComputedFrame computed = compute_frame(g, oracle);
  return *computed.find(term);  // raw: the oracle needs no denoising
}

// MAE over the reference's mean: a fraction, undefined (null, "n/a") for a reference whose
// mean is not above 0 (a black pass), where 0% would read as perfect.
nlohmann::json relative_mae_json(const ErrorStats& s) {
  return s.mean_reference > 0 ? nlohmann::json(s.mae / s.mean_reference) : nlohmann::json(nullptr);
}

std::string relative_mae_text(const ErrorStats& s) {
  if (!(s.mean_reference > 0)) return "relative n/a: the reference's mean is not above 0";
  char text[48];
  std::snprintf(text, sizeof text, "relative %.1f%%", 100.0 * s.mae / s.mean_reference);
  return text;
}

nlohmann::json stats_json(const ErrorStats& s) {
  return {{"mae", s.mae}, {"rmse", s.rmse}, {"bias", s.bias}, {"p95", s.p95}, {"max", s.max_abs},
          {"pixels", s.pixels}};
}

// Mean |error| per confidence decile, as JSON: one object per bin, [lo, hi), pixels, mae.
nlohmann::json deciles_json(const ConfidenceDeciles& d) {
  nlohmann::json bins = nlohmann::json::array();
  for (int b = 0; b < ConfidenceDeciles::kBins; ++b)
    bins.push_back({{"lo", b / 10.0}, {"hi", (b + 1) / 10.0}, {"pixels", d.pixels(b)}, {"mae", d.mae(b)}});
  return bins;
}

// The same as a table under the frame's (or the run's) line: the confidence predicts the
// error where low-confidence bins err more.
void print_deciles(const ConfidenceDeciles& d) {
  std::printf("  confidence     pixels   MAE\n");
  for (int b = 0; b < ConfidenceDeciles::kBins; ++b)
    std::printf("  [%.1f, %.1f%c %9lld   %.4f\n", 0.1 * b, 0.1 * (b + 1), b + 1 == ConfidenceDeciles::kBins ? ']' : ')',
                (long long)d.pixels(b), d.mae(b));
}

}  // namespace

int run_eval(const EvalArgs& args) {
  // Frames are computed in this process: the heap and the threads as in a worker.
  keep_freed_memory_for_reuse();
  apply_thread_budget(args.request.threads);
  ErrorAccumulator overall;
  ConfidenceDeciles overall_deciles;
  double overall_ms = 0;
  int failed = 0;
  // A file that gives no measurement: said on stderr, and listed under "failed" in --json.
  nlohmann::json failures = nlohmann::json::array();
  auto fail = [&](const std::string& file, const std::string& message) {
    std::cerr << "ssdo eval: " << message << "\n";
    failures.push_back({{"path", file}, {"error", message}});
    ++failed;
  };
  nlohmann::json files = nlohmann::json::array();
  const std::string method(to_string(args.request.ao.method));
  if (!args.heatmap_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(args.heatmap_dir, ec);
    if (ec || !std::filesystem::is_directory(args.heatmap_dir, ec)) {
      std::cerr << "ssdo eval: --heatmap " << args.heatmap_dir << ": cannot create the folder"
                << (ec ? ": " + ec.message() : std::string(" (a file of that name is in the way)")) << "\n";
      return 2;
    }
    // One heatmap per file name: two files of one name (in two folders) would replace each
    // other's, silently.
    std::map<std::string, std::string> file_of_stem;
    for (const std::string& file : args.files) {
      const auto [it, fresh] = file_of_stem.emplace(std::filesystem::path(file).stem().string(), file);
      if (!fresh && it->second != file) {
        std::cerr << "ssdo eval: " << it->second << " and " << file << " would both write the heatmap "
                  << (std::filesystem::path(args.heatmap_dir) / (it->first + ".error.exr")).string()
                  << " (the same file name): evaluate them with different --heatmap folders\n";
        return 2;
      }
    }
    // A heatmap is never written over a frame being evaluated ("a.exr" beside "a.error.exr").
    for (const std::string& file : args.files) {
      const std::filesystem::path map =
          std::filesystem::path(args.heatmap_dir) / (std::filesystem::path(file).stem().string() + ".error.exr");
      for (const std::string& input : args.files) {
        std::error_code ec;
        if (!std::filesystem::equivalent(map, input, ec) || ec) continue;
        std::cerr << "ssdo eval: the heatmap of " << file << " would be written over the input " << input
                  << ": choose another --heatmap folder\n";
        return 2;
      }
    }
  }

  // With --views, the files of one shot are each other's extra views, read once each as
  // `process` reads them.
  const auto neighbours = sequence_neighbours(
      args.files, neighbour_places(args.request.views_per_side, args.request.temporal_per_side));
  // A light term compared with a pass lit by the frame's own world says nothing without
  // that world: say so once (on stderr, which --json leaves clean).
  if (args.term != "ao" && args.oracle_preset.empty() && !args.request.environment)
    std::cerr << "ssdo eval: note: no --env, --sky or --env-constant: " << args.term
              << " is lit by uniform radiance 1, the reference pass '" << args.reference
              << "' by whatever lit the render; give the render's environment to compare them\n";
  SequenceContext sequence;
  // A neighbour is computed later when it comes later in the files, whatever its number.
  std::map<std::string, size_t> position;
  for (size_t i = 0; i < args.files.size(); ++i) position.emplace(args.files[i], i);
  for (size_t index = 0; index < args.files.size(); ++index) {
    const std::string& file = args.files[index];
    ReadOptions read = args.request.read;
    read.read_references = true;
    FrameRequest sequence_request = args.request;
    sequence_request.input_path = file;
    sequence_request.neighbours = neighbours[index];
    for (NeighbourFrame& n : sequence_request.neighbours) n.computed_later = position.at(n.path) > index;
    give_neighbours_camera(sequence_request.neighbours, sequence_request.read.camera_json);
    ReadResult frame = sequence.read(sequence_request, read);
    if (!frame.ok()) {
      fail(file, frame.error);
      continue;
    }
    const auto ref_it = frame.gbuffer.references.find(args.reference);
    if (args.oracle_preset.empty() && ref_it == frame.gbuffer.references.end()) {
      std::string present;
      for (const auto& [name, img] : frame.gbuffer.references) present += (present.empty() ? "" : ", ") + name;
      fail(file, file + ": no reference pass '" + args.reference +
                     "' (reference passes present: " + (present.empty() ? "none" : present) + ")");
      for (const std::string& note : frame.info.notes)
        if (note.rfind("reference:", 0) == 0) std::cerr << "  " << note << "\n";
      continue;
    }
    // The radius as process computes it: the frame's AO distance (the AO reference's
    // radius) unless --radius is given.
    FrameRequest request = sequence_request;
    if (std::string error; !resolve_frame_radius(request, frame.info, error)) {
      fail(file, error);
      continue;
    }

    const auto t0 = std::chrono::steady_clock::now();
    std::vector<std::string> notes;  // (eval prints no notes)
    const ComputedFrame computed = sequence.compute(request, read, GBuffer(frame.gbuffer), notes);
    const double ms = ms_since(t0);
    const std::string name = args.term + (args.raw ? "" : "_denoised");
    const cv::Mat* found = computed.find(name);
    if (!found) {
      fail(file, file + ": term '" + name + "' was not computed");
      continue;
    }
    // Scalar terms (AO) compare with a scalar reference (Cycles' AO is R = G = B);
    // colour terms compare the channel mean of each pixel.
    const cv::Mat estimate = to_single_channel(*found);
    cv::Mat reference;
    if (args.oracle_preset.empty()) {
      reference = to_single_channel(ref_it->second);
    } else {
      const cv::Mat oracle = oracle_term(frame.gbuffer, request, args.term, args.oracle_preset);
      reference = oracle.channels() == 1 ? oracle : to_single_channel(oracle);
    }
    const ErrorStats s = compare_images(estimate, reference, frame.gbuffer.mask);
    // An error over no pixel is no measurement (an MAE of 0 would read as perfect).
    const int64_t foreground = frame.info.foreground_pixels;
    if (const std::string reason = no_comparison_reason(s.pixels, foreground); !reason.empty()) {
      fail(file, file + ": " + reason);
      continue;
    }
    if (const std::string note = left_out_note(s.pixels, foreground); !note.empty())
      std::cerr << "ssdo eval: " << file << ": " << note << "\n";
    overall.add(estimate, reference, frame.gbuffer.mask);
    ConfidenceDeciles deciles;
    if (const cv::Mat* confidence = computed.find(output_term_name(OutputTermId::confidence)))  // stored in half
      deciles.add(estimate, reference, to_single_channel(*confidence), frame.gbuffer.mask);
    overall_deciles.add(deciles);
    overall_ms += ms;

    nlohmann::json j = stats_json(s);
    j["file"] = file;
    j["method"] = args.term == "ao" ? method : std::string(to_string(request.ssdo.method));
    j["term"] = args.term;
    j["relative_mae"] = relative_mae_json(s);
    j["reference"] = args.oracle_preset.empty() ? args.reference : "oracle:" + args.oracle_preset;
    j["preset"] = args.preset;
    j["radius"] = request.ao.radius_world;
    j["ms"] = ms;
    j["confidence_deciles"] = deciles_json(deciles);
    files.push_back(j);
    if (!args.json) {
      std::printf("%s: %s %s %s r=%.3g  MAE %.4f (%s)  RMSE %.4f  bias %+.4f  p95 %.4f  (%d px, %.1f ms)\n",
                  file.c_str(), args.term.c_str(), j["method"].get<std::string>().c_str(), args.preset.c_str(),
                  request.ao.radius_world, s.mae, relative_mae_text(s).c_str(), s.rmse, s.bias, s.p95,
                  int(s.pixels), ms);
      print_deciles(deciles);
    }
    if (!args.heatmap_dir.empty()) {
      const std::string stem = std::filesystem::path(file).stem().string();
      const std::string out = (std::filesystem::path(args.heatmap_dir) / (stem + ".error.exr")).string();
      WriteOptions w;
      w.png_previews = true;
      const std::string err = write_outputs(
          out, {{"error", error_heatmap(estimate, reference, frame.gbuffer.mask), SampleType::half, false},
                {args.term, estimate, SampleType::float32, false},
                {"reference", reference, SampleType::float32, false}},
          frame.gbuffer.camera, w);
      if (!err.empty()) fail(file, err);
    }
  }
  const ErrorStats all = overall.result();
  if (args.json) {
    nlohmann::json o = stats_json(all);
    o["ms"] = overall_ms;
    o["files"] = int(files.size());
    o["relative_mae"] = relative_mae_json(all);
    o["confidence_deciles"] = deciles_json(overall_deciles);
    // Names that are not UTF-8 (file names are bytes) come out with U+FFFD in their place.
    const nlohmann::json all = {{"files", files}, {"failed", failures}, {"overall", o}};
    std::cout << all.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  } else if (args.files.size() > 1) {
    std::printf("overall: MAE %.4f (%s)  RMSE %.4f  bias %+.4f  p95 %.4f  (%d px, %.1f ms)\n", all.mae,
                relative_mae_text(all).c_str(), all.rmse, all.bias, all.p95, int(all.pixels), overall_ms);
    print_deciles(overall_deciles);
  }
  return failed ? 1 : 0;
}

Command register_eval(CLI::App& app) {
  auto st = std::make_shared<CommandState<EvalArgs>>();
  EvalArgs& e = st->args;
  st->options.compute.preset = "high";
  CLI::App* cmd = app.add_subcommand(
      "eval", "Compare computed AO with a reference pass of the same frame (e.g. Cycles' "
              "ray-traced AO) over foreground pixels: MAE, RMSE, bias, 95th percentile, time, and "
              "the MAE per confidence decile (pixels binned by the confidence channel)");
  cmd->add_option("files", e.files, "EXR frames holding the reference pass")->required();
  cmd->add_option("--reference", e.reference,
                  "Reference pass name (default: the term's Cycles pass: AO, DiffDir or DiffInd)");
  cmd->add_option("--term", e.term,
                  "Term to compare: ao (with --reference AO), ssdo_direct (--reference DiffDir) "
                  "or ssdo_indirect (--reference DiffInd); a colour term is compared by the mean of its R, G "
                  "and B per pixel (its grey level: an error of hue alone is not counted)")
      ->check(CLI::IsMember({"ao", "ssdo_direct", "ssdo_indirect"}))
      ->capture_default_str();
  cmd->add_flag("--raw", e.raw, "Compare the raw term instead of the denoised one");
  cmd->add_option("--against-oracle", e.oracle_preset,
                  "Compare with the screen-space oracle at this preset (raymarch for AO, the "
                  "SSDO oracle for light terms; same radius and thickness) instead of a pass: "
                  "the method's estimator error alone")
      ->check(CLI::IsMember({"low", "medium", "high", "ultra"}));
  cmd->add_flag("--json", e.json,
                "Print JSON: \"files\" (one entry per measured file), \"failed\" (path and error of each file "
                "that gave no measurement) and \"overall\"");
  cmd->add_option("--heatmap", e.heatmap_dir,
                  "Write an error image per file into DIR: NAME.error.exr (channels error, the term, reference) "
                  "and its pictures NAME.error.png (the error), NAME.error.<term>.png, NAME.error.reference.png");
  add_frame_options(*cmd, st->options, int(OptionSet::read) | int(OptionSet::compute));
  return {cmd, [st] {
            EvalArgs& eval = st->args;
            // The terms are the compared one's (the environment is built only for SSDO's).
            ComputeOptionArgs compute = st->options.compute;
            compute.terms = eval.term == "ao" ? "ao" : "ssdo";
            std::string error;
            if (!resolve_read_options(st->options.read, eval.request.read, error) ||
                !resolve_compute_options(compute, eval.request, error))
              return usage_error(error);
            if (const std::string note = quality_choice_note(eval.request); !note.empty())
              std::cerr << "ssdo eval: " << note << "\n";
            eval.request.terms = {eval.term == "ao", eval.term != "ao", false};  // no composite
            if (eval.reference.empty())
              eval.reference = eval.term == "ao" ? "AO" : eval.term == "ssdo_direct" ? "DiffDir" : "DiffInd";
            eval.preset = effective_preset(compute, eval.request, eval.term != "ao");
            eval.files = each_file_once(eval.files);  // a file listed twice counts once
            return run_eval(eval);
          }};
}

}  // namespace ssdo
