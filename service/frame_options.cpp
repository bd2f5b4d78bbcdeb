#include "service/frame_options.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

namespace ssdo {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
const std::vector<std::string> kPresets = {"low", "medium", "high", "ultra"};
const std::vector<std::string> kAoMethods = {"hemisphere", "hbao", "gtao", "raymarch"};

using A = FrameOptionArgs;

std::vector<FrameOption> read_options() {
  return {
      {.name = "map", .kind = OptionKind::list, .set = OptionSet::read, .group = "Input",
       .help = "Channel for an input, for renderers no profile knows: INPUT=CHANNEL, INPUT one of depth, depth-back "
               "(a back-face depth pass), normal, position, albedo, lighting, normal-space, position-space "
               "(world|view), or ref:NAME. A CHANNEL may be a layer (N -> N.X N.Y N.Z). Repeatable.",
       .field = +[](A& a) -> std::vector<std::string>& { return a.read.maps; }},
      {.name = "camera", .kind = OptionKind::text, .set = OptionSet::read, .group = "Input",
       .help = "Camera JSON sidecar", .unset = "NAME.camera.json beside NAME.exr", .file = true,
       .field = +[](A& a) -> std::string& { return a.read.camera_json; }},
      {.name = "fov", .kind = OptionKind::number, .set = OptionSet::read, .group = "Input",
       .help = "Horizontal field of view in degrees, for frames with neither a sidecar nor worldToCamera/worldToNDC "
               "header attributes",
       .unset = "the frame's camera", .lo = 0.1, .hi = 179.9, .zero_unset = true,
       .field = +[](A& a) -> float& { return a.read.fov_x_deg; }},
      {.name = "depth-kind", .kind = OptionKind::choice, .set = OptionSet::read, .group = "Input",
       .help = "Depth convention: planar (distance along the view axis), radial (distance from the eye) or auto (as "
               "the sidecar says, else planar)",
       .choices = {"auto", "planar", "radial"}, .field = +[](A& a) -> std::string& { return a.read.depth_kind; }},
      {.name = "part", .kind = OptionKind::text, .set = OptionSet::read, .group = "Input",
       .help = "Multi-part EXR: the part that holds depth", .unset = "the first part with depth",
       .field = +[](A& a) -> std::string& { return a.read.part; }},
  };
}

std::vector<FrameOption> compute_options() {
  return {
      {.name = "method", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "Compute",
       .help = "AO method: hemisphere, hbao, gtao, raymarch (slow oracle)", .choices = kAoMethods,
       .field = +[](A& a) -> std::string& { return a.compute.method; }},
      {.name = "preset", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "Compute",
       .help = "Quality preset: low, medium, high, ultra", .choices = kPresets,
       .field = +[](A& a) -> std::string& { return a.compute.preset; }},
      {.name = "radius", .kind = OptionKind::number, .set = OptionSet::compute, .group = "Compute",
       .help = "AO and SSDO radius in scene units",
       .unset = "the frame's AO distance when its sidecar gives one, else 1", .lo = 1e-9, .hi = 1e12,
       .zero_unset = true,
       .field = +[](A& a) -> float& { return a.compute.radius_world; }},
      {.name = "thickness", .kind = OptionKind::number, .set = OptionSet::compute, .group = "Compute",
       .help = "Assumed thickness of surfaces in scene units", .unset = "the method's", .lo = 1e-9, .hi = kInf,
       .zero_unset = true,
       .field = +[](A& a) -> float& { return a.compute.thickness_world; }},
      {.name = "thickness-model", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "Compute",
       .help = "How deep a surface is taken to be behind what the frame shows, where it has no back-face depth, "
               "for GTAO and raymarch AO: constant (--thickness) or silhouettes (as deep as it is wide from its "
               "nearest silhouette: thin things thin, walls and floors solid; a third less error against "
               "ray-traced AO on most frames, a little more under objects that float free). SSDO keeps the "
               "constant, but for what --views decide",
       .unset = "silhouettes for gtao, constant for raymarch; constant when --thickness is given",
       .choices = {"", "constant", "silhouettes"},
       .field = +[](A& a) -> std::string& { return a.compute.thickness_model; }},
      {.name = "threads", .kind = OptionKind::integer, .set = OptionSet::compute, .group = "Compute",
       .help = "Threads per frame (at most the cores); without --jobs, process and serve then run cores / THREADS "
               "frames at once over the cores the process may use (its CPU affinity)",
       .unset = "all cores", .lo = 0, .hi = 1024,
       .field = +[](A& a) -> int& { return a.compute.threads; }},
      {.name = "terms", .kind = OptionKind::text, .set = OptionSet::compute, .group = "Compute",
       .help = "Terms to compute and write: ao (AO, bent normal), ssdo (SSDO direct and indirect, and the composite "
               "they light), composite, all",
       .field = +[](A& a) -> std::string& { return a.compute.terms; }},
      {.name = "multibounce", .kind = OptionKind::flag, .set = OptionSet::compute, .group = "Compute",
       .help = "Multi-bounce AO (Jimenez et al. 2016, eq. 10): brightens AO by the light that bounces between "
               "surfaces of the frame's albedo (its Rec. 709 luminance: AO is one channel; read when given; "
               "without albedo AO is single-bounce)",
       .field = +[](A& a) -> bool& { return a.compute.multibounce; }},
      {.name = "composite", .kind = OptionKind::text, .set = OptionSet::compute, .group = "Compute",
       .help = "Composite terms: a mode (off, ssao, ssdo, ssao+ssdo) or a weighted list of ambient, ambient_ao, "
               "ssdo_direct, ssdo_indirect, lighting, e.g. ambient_ao:0.5,ssdo_direct,ssdo_indirect",
       .unset = "ssdo when SSDO is computed, else ssao",
       .field = +[](A& a) -> std::string& { return a.compute.composite; }},
      {.name = "quality", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "Compute",
       .help = "auto: the fastest method and preset whose error on the shipped calibration frames (MAE against "
               "ray-traced AO) is at most --max-error; the choice is printed",
       .unset = "--method and --preset as given", .choices = {"", "auto"},
       .field = +[](A& a) -> std::string& { return a.compute.quality; }},
      {.name = "max-error", .kind = OptionKind::number, .set = OptionSet::compute, .group = "Compute",
       .help = "Largest acceptable MAE for --quality auto", .lo = 0, .hi = 1,
       .field = +[](A& a) -> float& { return a.compute.max_error; }},
      {.name = "views", .kind = OptionKind::integer, .set = OptionSet::compute, .group = "Compute",
       .help = "A frame of a sequence (a pattern with --frames, or files whose names differ in a frame number) "
               "uses up to K neighbouring frames on each side as extra views of what it hides: among the frames "
               "within 3K, the ones whose camera moved enough to see something new; only their depth and camera "
               "are read, once each. 0 = every frame alone",
       .lo = 0, .hi = 8, .field = +[](A& a) -> int& { return a.compute.views; }},
      {.name = "temporal", .kind = OptionKind::integer, .set = OptionSet::compute, .group = "Compute",
       .help = "A frame of a sequence gets its denoised terms (ao_denoised, ssdo_*_denoised) from its raw terms "
               "filtered over the raw terms of up to K frames on each side, past and future, each reprojected "
               "through depth and both cameras; what another frame sees differently (a disocclusion, a moving "
               "object, a cut) is left out, and there the frame keeps its own. Less flicker, and a low preset "
               "approaches a high one; each frame's raw terms are computed once per batch. The raw terms stay "
               "unfiltered. 0 = every frame alone",
       .lo = 0, .hi = 8, .field = +[](A& a) -> int& { return a.compute.temporal; }},
  };
}

std::vector<FrameOption> ssdo_options() {
  return {
      {.name = "ssdo-method", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "SSDO",
       .help = "SSDO method: ssdo (fast) or oracle (slow screen-space best case)", .choices = {"ssdo", "oracle"},
       .field = +[](A& a) -> std::string& { return a.compute.ssdo_method; }},
      {.name = "ssdo-preset", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "SSDO",
       .help = "SSDO quality preset", .unset = "--preset", .choices = {"", "low", "medium", "high", "ultra"},
       .field = +[](A& a) -> std::string& { return a.compute.ssdo_preset; }},
      {.name = "env", .kind = OptionKind::text, .set = OptionSet::compute, .group = "SSDO",
       .help = "Environment light: an equirectangular radiance map (EXR; row 0 = straight up, centre column = +Y "
               "world as Blender/Cycles writes it)",
       .unset = "constant radiance 1", .file = true, .existing_file = true,
       .field = +[](A& a) -> std::string& { return a.compute.env_path; }},
      {.name = "sky", .kind = OptionKind::text, .set = OptionSet::compute, .group = "SSDO",
       .help = "Environment light: a two-colour sky TOP,BOTTOM, each a grey level or R:G:B, e.g. --sky "
               "0.25:0.5:1,1:0.35:0.08",
       .field = +[](A& a) -> std::string& { return a.compute.sky; }},
      {.name = "env-constant", .kind = OptionKind::number, .set = OptionSet::compute, .group = "SSDO",
       .help = "Environment light: uniform radiance, at most the largest half float (the outputs store radiance "
               "in half)",
       .unset = "1 unless --env or --sky", .lo = 1e-9, .hi = kMaxRadiance, .zero_unset = true,
       .field = +[](A& a) -> float& { return a.compute.env_constant; }},
      {.name = "env-up", .kind = OptionKind::choice, .set = OptionSet::compute, .group = "SSDO",
       .help = "World up axis of the environment: z (Blender) or y", .choices = {"z", "y"},
       .field = +[](A& a) -> std::string& { return a.compute.env_up; }},
  };
}

std::vector<FrameOption> output_options() {
  return {
      {.name = "compression", .kind = OptionKind::choice, .set = OptionSet::output, .group = "Output",
       .help = "EXR compression: zip (deflate level 1), zips, piz, rle, none (all lossless); dwaa (lossy, files of "
               "colour terms only)",
       .choices = {"zip", "zips", "piz", "rle", "none", "dwaa"},
       .field = +[](A& a) -> std::string& { return a.compression; }},
      {.name = "png", .kind = OptionKind::flag, .set = OptionSet::output, .group = "Output",
       .help = "Also write an sRGB PNG preview per term", .field = +[](A& a) -> bool& { return a.png; }},
      {.name = "io-only", .kind = OptionKind::flag, .set = OptionSet::output, .group = "Output",
       .help = "Benchmark the I/O floor: read and write what the terms would, with stand-in images, computing "
               "nothing",
       .field = +[](A& a) -> bool& { return a.io_only; }},
      {.name = "guard-band", .kind = OptionKind::integer, .set = OptionSet::output, .group = "Output",
       .help = "Frames rendered with overscan: crop PX pixels off each side of every output after computing on the "
               "whole frame, so that taps near the borders see the occluders just outside the picture; the written "
               "camera covers the inner frame",
       .unset = "no crop", .lo = 0, .hi = 4096, .field = +[](A& a) -> int& { return a.guard_band_px; }},
  };
}

std::string join(const std::vector<std::string>& values) {
  std::string s;
  for (const std::string& v : values)
    if (!v.empty()) s += (s.empty() ? "" : ", ") + v;
  return s;
}

const char* kind_text(OptionKind kind) {
  switch (kind) {
    case OptionKind::text: return "text";
    case OptionKind::choice: return "choice";
    case OptionKind::number: return "number";
    case OptionKind::integer: return "integer";
    case OptionKind::flag: return "flag";
    case OptionKind::list: return "list";
  }
  return "";
}

// The value of a default-constructed FrameOptionArgs, as the docs show it.
std::string default_text(const FrameOption& o) {
  FrameOptionArgs defaults;
  return std::visit(
      [&](auto field) -> std::string {
        const nlohmann::json v = field(defaults);
        if (v.is_string()) return v.get<std::string>().empty() ? "" : "`" + v.get<std::string>() + "`";
        if (v.is_array()) return "";
        return "`" + (v.is_number_float() ? number_text(v.get<double>()) : v.dump()) + "`";
      },
      o.field);
}

// A Markdown table cell: '|' would end it.
std::string cell(const std::string& text) {
  std::string out;
  for (char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

std::string markdown_row(const FrameOption& o) {
  std::string type = kind_text(o.kind);
  if (o.kind == OptionKind::choice) type = join(o.choices);
  if (o.kind == OptionKind::number || o.kind == OptionKind::integer) type += " " + describe_range(o);
  std::string def = default_text(o);
  if (*o.unset) def += def.empty() ? std::string(o.unset) : ": " + std::string(o.unset);
  return "| `--" + std::string(o.name) + "` | " + cell(type) + " | " + cell(def) + " | " + cell(o.help) + " |\n";
}

}  // namespace

const std::vector<FrameOption>& frame_options() {
  static const std::vector<FrameOption> table = [] {
    std::vector<FrameOption> all;
    for (auto part : {read_options, compute_options, ssdo_options, output_options}) {
      std::vector<FrameOption> p = part();
      all.insert(all.end(), p.begin(), p.end());
    }
    return all;
  }();
  return table;
}

const FrameOption* find_frame_option(const std::string& name) {
  const auto& table = frame_options();
  const auto it = std::find_if(table.begin(), table.end(), [&](const FrameOption& o) { return name == o.name; });
  return it == table.end() ? nullptr : &*it;
}

std::string describe_range(const FrameOption& o) {
  return "[" + number_text(o.lo) + ", " + number_text(o.hi) + (std::isinf(o.hi) ? ")" : "]");
}

std::string check_choice(const FrameOption& o, const std::string& value) {
  if (std::find(o.choices.begin(), o.choices.end(), value) != o.choices.end()) return {};
  return "'" + value + "' is not one of " + join(o.choices);
}

std::string check_number(const FrameOption& o, double value) {
  // Number options are float fields: a finite double beyond a float's range would become
  // inf in the field, past every range check.
  if (o.kind == OptionKind::number && std::isfinite(value) && std::abs(value) > std::numeric_limits<float>::max())
    return "must be at most " + number_text(std::numeric_limits<float>::max()) + " in magnitude (a float)";
  const bool in_range = std::isfinite(value) && value >= o.lo && value <= o.hi;
  const bool integral = o.kind != OptionKind::integer || value == std::floor(value);
  if ((in_range || (o.zero_unset && value == 0)) && integral) return {};
  return std::string("must be ") + (o.zero_unset ? "0 (unset) or " : "") +
         (o.kind == OptionKind::integer ? "an integer" : "a number") + " in " + describe_range(o);
}

std::string number_text(double v) {
  if (std::isinf(v)) return "inf";
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string frame_options_markdown() {
  std::string md =
      "# Frame options\n\n"
      "<!-- Generated by `ssdo options --markdown` from service/frame_options.cpp; a test checks that this file\n"
      "     matches. Edit the table there, then regenerate. -->\n\n"
      "Every option that decides a frame's output is spelled the same everywhere: `--NAME VALUE` on the command\n"
      "line (`ssdo process`, `serve`, `client`; `info`, `bench` and `eval` take the ones they use), `\"NAME\": VALUE`\n"
      "in a `--config` JSON file (flags given on the command line win), and in the `\"options\"` object of a\n"
      "socket request. Flags are `true`/`false` in JSON; a list takes a JSON list or one string.\n";
  std::string group;
  for (const FrameOption& o : frame_options()) {
    if (group != o.group) {
      group = o.group;
      md += "\n## " + group + "\n\n| Option | Type | Default | Meaning |\n|---|---|---|---|\n";
    }
    md += markdown_row(o);
  }
  return md;
}

}  // namespace ssdo
