#include "service/cli_options.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <type_traits>
#include <variant>

#include "formats/env_map.h"
#include "service/parallelism.h"
#include "service/quality.h"
#include "service/request_options.h"

namespace ssdo {

namespace {

// A number as a person writes one: decimal digits, point, exponent and signs only (std::stod
// also reads "0x10" as 16 and "inf", which no option means).
bool decimal_text(const std::string& text) {
  return !text.empty() && text.find_first_not_of("0123456789.eE+-") == std::string::npos;
}

// A CLI11 validator running the table's own check, so that the command line and JSON
// accept the same values with the same message.
CLI::Validator table_check(const FrameOption& o) {
  return CLI::Validator(
      [&o](std::string& value) -> std::string {
        if (o.kind == OptionKind::choice) return check_choice(o, value);
        try {
          size_t used = 0;
          const double v = decimal_text(value) ? std::stod(value, &used) : 0.0;
          if (decimal_text(value) && used == value.size()) return check_number(o, v);
        } catch (const std::exception&) {
        }
        return check_number(o, std::numeric_limits<double>::quiet_NaN());
      },
      "", o.name);
}

// An empty value on the command line is a script's unset variable ("--env \"$SKY\"",
// "--chunk \"$TASK\""), not a choice: refused, where it would silently give the default (a
// JSON config's "" is the default, as the options a header records are written). Checked
// before any other check of the option, so that the message says what happened.
constexpr const char* kEmptyValueCheck = "empty-value";
CLI::Validator empty_value_check(const std::string& message) {
  return CLI::Validator([message](std::string& value) { return value.empty() ? message : std::string(); }, "",
                        kEmptyValueCheck);
}

// One table entry as a CLI11 option bound to its field in `args`.
void add_frame_option(CLI::App& app, const FrameOption& o, FrameOptionArgs& args) {
  const std::string flag = "--" + std::string(o.name);
  const std::string help = *o.unset ? std::string(o.help) + " (default" + (o.zero_unset ? ", also given as 0" : "") +
                                          ": " + o.unset + ")"
                                    : std::string(o.help);
  CLI::Option* opt = std::visit(
      [&](auto field) -> CLI::Option* {
        auto& value = field(args);
        if constexpr (std::is_same_v<std::decay_t<decltype(value)>, bool>) return app.add_flag(flag, value, help);
        else return app.add_option(flag, value, help);
      },
      o.field);
  opt->group(o.group);
  if (o.kind != OptionKind::flag)
    opt->check(empty_value_check(std::string("an empty value; leave the option out for the default") +
                                 (*o.unset ? std::string(" (") + o.unset + ")" : std::string())));
  if (o.kind == OptionKind::choice || o.kind == OptionKind::number || o.kind == OptionKind::integer)
    opt->check(table_check(o));
  if (o.existing_file) opt->check(CLI::ExistingFile);
  if (o.kind != OptionKind::flag && o.kind != OptionKind::list && !*o.unset) opt->capture_default_str();
}

}  // namespace

void refuse_empty_values(CLI::App& app) {
  for (CLI::Option* opt : app.get_options()) {
    if (!opt->nonpositional() || opt->get_type_size_min() <= 0) continue;
    try {
      opt->get_validator(kEmptyValueCheck);  // a frame option's own, naming its default (add_frame_option)
    } catch (const CLI::OptionNotFound&) {
      opt->check(empty_value_check("an empty value"));
    }
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) refuse_empty_values(*sub);
}

void add_frame_options(CLI::App& app, FrameOptionArgs& args, int sets) {
  for (const FrameOption& o : frame_options())
    if ((sets & int(o.set)) != 0) add_frame_option(app, o, args);
}

bool given(const CLI::App& app, const std::string& key) {
  const CLI::Option* opt = app.get_option_no_throw("--" + key);
  return opt != nullptr && opt->count() > 0;
}

bool frame_options_over_config(const CLI::App& app, const std::string& config, FrameOptionArgs& options,
                               std::string& error) {
  if (!config.empty()) {
    nlohmann::json j;
    if (!load_json_file(config, j, error)) return false;
    // A flag on the command line wins over the config's key; the environment is one choice
    // of three keys, so --env on the command line also replaces a config's "sky".
    const auto environment_key = [](const std::string& key) {
      return key == "env" || key == "sky" || key == "env-constant";
    };
    const bool environment_given = given(app, "env") || given(app, "sky") || given(app, "env-constant");
    const auto keep = [&](const std::string& key) {
      return given(app, key) || (environment_given && environment_key(key));
    };
    if (!apply_json(j, options, error, keep)) {
      error = config + ": " + error;
      return false;
    }
  }
  // The workers read and build what they compute with; here only the checks.
  FrameRequest check;
  if (!resolve_frame_options(options, check, error, /*build_environment=*/false)) return false;
  // Options given that change nothing with the others: said once, not an error (a config
  // shared by several commands may hold them).
  const ComputeOptionArgs& c = options.compute;
  if (c.quality != "auto" && given(app, "max-error"))
    std::fprintf(stderr, "ssdo: note: --max-error has no effect without --quality auto\n");
  if (TermSelection terms; !c.composite.empty() && parse_terms(c.terms, terms, error) && !terms.composite)
    std::fprintf(stderr, "ssdo: note: --composite has no effect: --terms %s writes no composite\n", c.terms.c_str());
  if (const std::string note = quality_choice_note(check); !note.empty())
    std::fprintf(
        stderr, "ssdo: %s%s\n", note.c_str(),
        given(app, "method") || given(app, "preset")
            ? " (AO's --method and --preset give way to --quality auto; SSDO keeps --ssdo-preset, else --preset)"
            : "");
  return true;
}

std::string effective_preset(const ComputeOptionArgs& a, const FrameRequest& request, bool ssdo) {
  if (ssdo) return a.ssdo_preset.empty() ? a.preset : a.ssdo_preset;
  if (!request.quality) return a.preset;
  return std::string(to_string(request.quality->entry.preset));
}

std::string quality_choice_note(const FrameRequest& request) {
  if (!request.quality) return {};
  const QualityChoice& q = *request.quality;
  char text[256];
  std::snprintf(text, sizeof text, "--quality auto --max-error %.3g: %s %s (calibrated MAE %.3f, %.0f ms at 640x360)%s",
                q.max_error, std::string(to_string(q.entry.method)).c_str(),
                std::string(to_string(q.entry.preset)).c_str(), q.entry.mae, q.entry.ms,
                q.met ? "" : "; no method reaches that error, this is the most accurate");
  return text;
}

CLI::Validator seconds_in(double lo, double hi) {
  const std::string range = "[" + number_text(lo) + ", " + number_text(hi) + "]";
  return CLI::Validator(
      [lo, hi, range](std::string& value) -> std::string {
        try {
          size_t used = 0;
          const double v = std::stod(value, &used);
          if (used == value.size() && std::isfinite(v) && v >= lo && v <= hi) return {};
        } catch (const std::exception&) {
        }
        return "'" + value + "' is not a number of seconds in " + range;
      },
      "SECONDS in " + range);
}

void add_worker_limits(CLI::App& cmd, int& jobs, WorkerLimits& limits) {
  cmd.add_option("-j,--jobs", jobs,
                 "Worker processes = frames computed at once, each with cores/jobs threads (0 = "
                 "process: 1 worker with every core; serve: one worker per core)")
      ->check(CLI::Range(0, 256))
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
  cmd.add_option("--frame-timeout", limits.frame_timeout_s,
                 "Seconds a frame may take (read + compute + write) before its worker is killed; time the job is "
                 "suspended (SIGSTOP) does not count")
      ->check(seconds_in(0.001, 604800.0))
      ->capture_default_str()
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
  cmd.add_option("--memory-limit", limits.memory_limit_mb, "Address-space limit of each worker, MiB")
      ->check(CLI::Range(int64_t(256), int64_t(1) << 22))
      ->capture_default_str()
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
  cmd.add_option("--max-pixels", limits.max_pixels, "Largest frame (width x height) a worker decodes")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 34))
      ->capture_default_str()
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
      ->group("Workers");
}

bool parse_sky(const std::string& spec, glm::vec3& top, glm::vec3& bottom, std::string& error) {
  // Tokenise on ',' ':' and whitespace, keeping where the commas were.
  std::vector<std::vector<float>> groups(1);
  std::string token;
  auto flush = [&]() {
    if (token.empty()) return true;
    try {
      size_t used = 0;
      if (!decimal_text(token)) throw std::invalid_argument(token);
      const float v = std::stof(token, &used);
      if (used != token.size() || !(v >= 0.0f) || !std::isfinite(v)) throw std::invalid_argument(token);
      if (v > kMaxRadiance) {
        error = "--sky '" + spec + "': '" + token + "' is over " + std::to_string(int(kMaxRadiance)) +
                " (the largest half float: the outputs store radiance in half)";
        return false;
      }
      groups.back().push_back(v);
    } catch (const std::exception&) {
      error = "--sky '" + spec + "': '" + token + "' is not a non-negative number";
      return false;
    }
    token.clear();
    return true;
  };
  for (char c : spec) {
    if (c == ',' || c == ':' || std::isspace(static_cast<unsigned char>(c))) {
      if (!flush()) return false;
      if (c == ',') groups.emplace_back();
    } else {
      token += c;
    }
  }
  if (!flush()) return false;
  std::vector<float> all;
  for (const auto& g : groups) all.insert(all.end(), g.begin(), g.end());
  auto colour = [](const std::vector<float>& v, size_t at, size_t n) {
    return n == 1 ? glm::vec3(v[at]) : glm::vec3(v[at], v[at + 1], v[at + 2]);
  };
  if (groups.size() == 2 && (groups[0].size() == 1 || groups[0].size() == 3) &&
      (groups[1].size() == 1 || groups[1].size() == 3)) {
    top = colour(groups[0], 0, groups[0].size());
    bottom = colour(groups[1], 0, groups[1].size());
    return true;
  }
  if (all.size() == 6) {
    top = colour(all, 0, 3);
    bottom = colour(all, 3, 3);
    return true;
  }
  error = "--sky '" + spec + "': expected TOP,BOTTOM with each a grey level or R:G:B";
  return false;
}

bool parse_composite(const std::string& spec, std::vector<WeightedTerm>& terms, std::string& error) {
  if (const auto mode = parse_composite_mode(spec)) {
    terms = composite_mode_terms(*mode);
    return true;
  }
  terms.clear();
  std::stringstream ss(spec);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    const size_t colon = item.find(':');
    const std::string name = item.substr(0, colon);
    const auto term = parse_composite_term(name);
    if (!term) {
      error = "--composite: unknown term '" + name +
              "' (modes: off, ssao, ssdo, ssao+ssdo; terms: ambient, ambient_ao, ssdo_direct, "
              "ssdo_indirect, lighting)";
      return false;
    }
    WeightedTerm w{*term, 1.0f};
    if (colon != std::string::npos) {
      try {
        size_t used = 0;
        const std::string value = item.substr(colon + 1);
        w.weight = std::stof(value, &used);
        if (used != value.size()) throw std::invalid_argument(value);
      } catch (const std::exception&) {
        error = "--composite: the weight in '" + item + "' is not a number";
        return false;
      }
      if (!(w.weight >= 0.0f && w.weight <= 16.0f)) {
        error = "--composite: the weight in '" + item + "' is out of range [0, 16]";
        return false;
      }
    }
    if (std::any_of(terms.begin(), terms.end(), [&](const WeightedTerm& t) { return t.term == w.term; })) {
      error = "--composite: '" + name + "' is given twice (give each term once, with its weight)";
      return false;
    }
    terms.push_back(w);
  }
  if (terms.empty()) {
    error = "--composite: no term given";
    return false;
  }
  return true;
}

bool resolve_read_options(const ReadOptionArgs& a, ReadOptions& read, std::string& error) {
  read.camera_json = a.camera_json;
  if (a.fov_x_deg > 0) read.fov_x_deg = a.fov_x_deg;
  read.depth_kind = a.depth_kind == "planar"   ? DepthKind::planar
                    : a.depth_kind == "radial" ? DepthKind::radial
                                               : DepthKind::automatic;
  read.part = a.part;
  for (const std::string& m : a.maps) {
    const auto eq = m.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == m.size()) {
      error = "--map '" + m + "': expected INPUT=CHANNEL, e.g. depth=Z or normal=N";
      return false;
    }
    const std::string key = m.substr(0, eq), value = m.substr(eq + 1);
    ChannelMapping& map = read.mapping;
    auto space = [&](Space& s) {
      if (value == "world") s = Space::world;
      else if (value == "view") s = Space::view;
      else {
        error = "--map " + key + "=" + value + ": the space must be world or view";
        return false;
      }
      return true;
    };
    if (key == "depth") map.depth = value;
    else if (key == "depth-back") map.depth_back = value;
    else if (key == "normal") map.normal = value;
    else if (key == "position") map.position = value;
    else if (key == "albedo") map.albedo = value;
    else if (key == "lighting") map.lighting = value;
    else if (key == "normal-space") { if (!space(map.normal_space)) return false; }
    else if (key == "position-space") { if (!space(map.position_space)) return false; }
    else if (key.rfind("ref:", 0) == 0 && key.size() > 4) map.references[key.substr(4)] = value;
    else {
      error = "--map: unknown input '" + key +
              "' (depth, depth-back, normal, position, albedo, lighting, normal-space, position-space, "
              "ref:NAME)";
      return false;
    }
  }
  return true;
}

namespace {

// AO and SSDO settings: the method and preset (or --quality auto's choice from the shipped
// calibration), then the overrides, then the kernels' own validation.
bool resolve_settings(const ComputeOptionArgs& a, FrameRequest& request, std::string& error) {
  auto method = parse_ao_method(a.method);
  auto preset = parse_preset(a.preset);
  request.quality.reset();
  if (a.quality == "auto") {  // quality_choice_note says what was chosen, once per command
    QualityChoice q;
    q.max_error = a.max_error;
    q.entry = choose_quality(shipped_calibration(), a.max_error, q.met);
    method = q.entry.method;
    preset = q.entry.preset;
    request.quality = q;
  }
  if (!method || !preset) {
    error = "unknown method or preset: " + a.method + " / " + a.preset;
    return false;
  }
  if (a.thickness_model == "silhouettes" && a.thickness_world > 0) {
    error = "give --thickness (a constant thickness) or --thickness-model silhouettes, not both";
    return false;
  }
  request.ao = ao_preset(*method, *preset);
  if (a.radius_world > 0) request.ao.radius_world = a.radius_world;
  // A thickness given is a constant one; otherwise the model asked for, else the preset's.
  if (a.thickness_world > 0) {
    request.ao.thickness_world = a.thickness_world;
    request.ao.thickness_model = ThicknessModel::constant;
  } else if (!a.thickness_model.empty()) {
    request.ao.thickness_model =
        a.thickness_model == "silhouettes" ? ThicknessModel::silhouettes : ThicknessModel::constant;
  }
  request.ao.multibounce = a.multibounce;
  if (const std::string e = validate(request.ao); !e.empty()) {
    error = "AO settings: " + e;
    return false;
  }

  const auto ssdo_method = parse_ssdo_method(a.ssdo_method);
  const auto ssdo_level = parse_preset(a.ssdo_preset.empty() ? a.preset : a.ssdo_preset);
  if (!ssdo_method || !ssdo_level) {
    error = "unknown SSDO method or preset: " + a.ssdo_method + " / " + a.ssdo_preset;
    return false;
  }
  request.ssdo = ssdo_preset(*ssdo_method, *ssdo_level);
  if (a.radius_world > 0) request.ssdo.radius_world = a.radius_world;
  if (a.thickness_world > 0) request.ssdo.thickness_world = a.thickness_world;
  if (const std::string e = validate(request.ssdo); !e.empty()) {
    error = "SSDO settings: " + e;
    return false;
  }
  return true;
}

// The one environment light of --env, --sky or --env-constant (none: radiance 1).
bool resolve_environment(const ComputeOptionArgs& a, FrameRequest& request, std::string& error,
                         bool build_environment) {
  const int env_sources = int(!a.env_path.empty()) + int(!a.sky.empty()) + int(a.env_constant > 0);
  if (env_sources > 1) {
    error = "give one environment: --env, --sky or --env-constant";
    return false;
  }
  EnvironmentSettings env_settings;
  env_settings.up = a.env_up == "y" ? UpAxis::y : UpAxis::z;
  env_settings.filter_cone_half_angle_deg = filter_cone_half_angle_for_samples(request.ssdo.samples);
  if (!a.env_path.empty()) {
    // Without building it (a process that only checks the options): what is known without
    // decoding the pixels; the worker that builds it reports the rest.
    if (!build_environment) {
      error = check_env_map(a.env_path);
      return error.empty();
    }
    EnvMapResult env = read_env_map(a.env_path);
    if (!env.ok()) {
      error = env.error;
      return false;
    }
    request.environment =
        std::make_shared<const Environment>(Environment::equirect(env.radiance_rgb, env_settings));
  } else if (!a.sky.empty()) {
    SkyGradient sky;
    if (!parse_sky(a.sky, sky.top, sky.bottom, error)) return false;
    if (build_environment)
      request.environment = std::make_shared<const Environment>(Environment::sky(sky, env_settings));
  } else if (a.env_constant > 0 && build_environment) {
    request.environment =
        std::make_shared<const Environment>(Environment::constant(glm::vec3(a.env_constant), env_settings));
  }
  return true;
}

}  // namespace

bool resolve_compute_options(const ComputeOptionArgs& a, FrameRequest& request, std::string& error,
                             bool build_environment) {
  if (!resolve_settings(a, request, error)) return false;
  request.threads = frame_threads(a.threads);
  request.radius_given_world = a.radius_world;
  request.views_per_side = a.views;
  request.temporal_per_side = a.temporal;
  if (!parse_terms(a.terms, request.terms, error)) {
    error = "--terms: " + error;
    return false;
  }
  // AO alone never reads the light: the map is checked, not decoded.
  const bool uses_environment = request.terms.ssdo || request.terms.composite;
  if (!resolve_environment(a, request, error, build_environment && uses_environment)) return false;
  if (!a.composite.empty() && !parse_composite(a.composite, request.composite_terms, error)) return false;
  return true;
}

}  // namespace ssdo
