#include "service/cli_options.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "formats/env_map.h"
#include "service/quality.h"

namespace ssdo {

void add_read_options(CLI::App& app, ReadOptionArgs& a) {
  app.add_option("--map", a.maps,
                 "Channel for an input, for renderers no profile knows: INPUT=CHANNEL, INPUT one of "
                 "depth, normal, position, albedo, lighting, normal-space, position-space (world|view), "
                 "or ref:NAME. A CHANNEL may be a layer (N -> N.X N.Y N.Z). Repeatable.")
      ->group("Input");
  app.add_option("--camera", a.camera_json,
                 "Camera JSON sidecar (default: NAME.camera.json beside NAME.exr)")
      ->group("Input");
  app.add_option("--fov", a.fov_x_deg,
                 "Horizontal field of view in degrees, for frames with neither a sidecar nor "
                 "worldToCamera/worldToNDC header attributes")
      ->check(CLI::Range(0.1f, 179.9f))
      ->group("Input");
  app.add_option("--depth-kind", a.depth_kind,
                 "Depth convention: planar (distance along the view axis), radial (distance from "
                 "the eye) or auto (as the sidecar says, else planar)")
      ->check(CLI::IsMember({"auto", "planar", "radial"}))
      ->group("Input");
  app.add_option("--part", a.part, "Multi-part EXR: the part that holds depth")->group("Input");
}

void add_compute_options(CLI::App& app, ComputeOptionArgs& a, bool with_terms) {
  app.add_option("--method", a.method, "AO method: hemisphere, hbao, gtao, raymarch (slow oracle)")
      ->check(CLI::IsMember({"hemisphere", "hbao", "gtao", "raymarch"}))
      ->capture_default_str()
      ->group("Compute");
  app.add_option("--preset", a.preset, "Quality preset: low, medium, high, ultra")
      ->check(CLI::IsMember({"low", "medium", "high", "ultra"}))
      ->capture_default_str()
      ->group("Compute");
  app.add_option("--quality", a.quality,
                 "auto: the fastest method and preset whose error on the shipped calibration "
                 "frames (MAE against ray-traced AO) is at most --max-error; the choice is printed")
      ->check(CLI::IsMember({"auto"}))
      ->group("Compute");
  app.add_option("--max-error", a.max_error, "Largest acceptable MAE for --quality auto")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str()
      ->group("Compute");
  app.add_option("--radius", a.radius_world,
                 "AO radius in scene units (default: the frame's AO distance when its sidecar gives "
                 "one, else 1)")
      ->check(CLI::PositiveNumber)
      ->group("Compute");
  app.add_option("--thickness", a.thickness_world,
                 "Assumed thickness of surfaces in scene units (default: the method's)")
      ->check(CLI::PositiveNumber)
      ->group("Compute");
  app.add_option("--threads", a.threads, "Threads for the kernels (0 = all cores)")
      ->check(CLI::Range(0, 1024))
      ->group("Compute");
  if (!with_terms) return;
  app.add_option("--terms", a.terms, "Terms to compute and write: ao (AO, bent normal), ssdo (SSDO direct and indirect, and the composite they light), composite, all")
      ->capture_default_str()
      ->group("Compute");
  app.add_option("--ssdo-method", a.ssdo_method,
                 "SSDO method: ssdo (fast) or oracle (slow screen-space best case)")
      ->check(CLI::IsMember({"ssdo", "oracle"}))
      ->capture_default_str()
      ->group("SSDO");
  app.add_option("--ssdo-preset", a.ssdo_preset, "SSDO quality preset (default: --preset)")
      ->check(CLI::IsMember({"low", "medium", "high", "ultra"}))
      ->group("SSDO");
  app.add_option("--env", a.env_path,
                 "Environment light: an equirectangular radiance map (EXR; row 0 = straight up, "
                 "centre column = +Y world as Blender/Cycles writes it)")
      ->check(CLI::ExistingFile)
      ->group("SSDO");
  app.add_option("--sky", a.sky,
                 "Environment light: a two-colour sky TOP,BOTTOM, each a grey level or R:G:B, "
                 "e.g. --sky 0.25:0.5:1,1:0.35:0.08")
      ->group("SSDO");
  app.add_option("--env-constant", a.env_constant, "Environment light: uniform radiance (default 1)")
      ->check(CLI::NonNegativeNumber)
      ->group("SSDO");
  app.add_option("--env-up", a.env_up, "World up axis of the environment: z (Blender) or y")
      ->check(CLI::IsMember({"z", "y"}))
      ->capture_default_str()
      ->group("SSDO");
  app.add_option("--composite", a.composite,
                 "Composite terms: a mode (off, ssao, ssdo, ssao+ssdo) or a weighted list of "
                 "ambient, ambient_ao, ssdo_direct, ssdo_indirect, lighting, e.g. "
                 "ambient_ao:0.5,ssdo_direct,ssdo_indirect (default: ssdo when SSDO is "
                 "computed, else ssao)")
      ->group("Compute");
}

bool parse_sky(const std::string& spec, glm::vec3& top, glm::vec3& bottom, std::string& error) {
  // Tokenise on ',' ':' and whitespace, keeping where the commas were.
  std::vector<std::vector<float>> groups(1);
  std::string token;
  auto flush = [&]() {
    if (token.empty()) return true;
    try {
      size_t used = 0;
      const float v = std::stof(token, &used);
      if (used != token.size() || !(v >= 0.0f) || !std::isfinite(v)) throw std::invalid_argument(token);
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
    else if (key == "normal") map.normal = value;
    else if (key == "position") map.position = value;
    else if (key == "albedo") map.albedo = value;
    else if (key == "lighting") map.lighting = value;
    else if (key == "normal-space") { if (!space(map.normal_space)) return false; }
    else if (key == "position-space") { if (!space(map.position_space)) return false; }
    else if (key.rfind("ref:", 0) == 0 && key.size() > 4) map.references[key.substr(4)] = value;
    else {
      error = "--map: unknown input '" + key +
              "' (depth, normal, position, albedo, lighting, normal-space, position-space, ref:NAME)";
      return false;
    }
  }
  return true;
}

bool resolve_compute_options(const ComputeOptionArgs& a, FrameRequest& request, std::string& error,
                             bool build_environment) {
  auto method = parse_ao_method(a.method);
  auto preset = parse_preset(a.preset);
  if (a.quality == "auto") {
    bool met = false;
    const CalibrationEntry choice = choose_quality(shipped_calibration(), a.max_error, met);
    method = choice.method;
    preset = choice.preset;
    std::fprintf(stderr, "ssdo: --quality auto --max-error %.3g: %s %s (calibrated MAE %.3f, %.0f ms at 640x360)%s\n",
                 a.max_error, std::string(to_string(choice.method)).c_str(),
                 std::string(to_string(choice.preset)).c_str(), choice.mae, choice.ms,
                 met ? "" : "; no method reaches that error, this is the most accurate");
  }
  if (!method || !preset) {
    error = "unknown method or preset: " + a.method + " / " + a.preset;
    return false;
  }
  request.ao = ao_preset(*method, *preset);
  if (a.radius_world > 0) request.ao.radius_world = a.radius_world;
  if (a.thickness_world > 0) request.ao.thickness_world = a.thickness_world;
  request.threads = a.threads;
  if (!parse_terms(a.terms, request.terms, error)) {
    error = "--terms: " + error;
    return false;
  }
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
      if (std::string e = check_env_map(a.env_path); !e.empty()) {
        error = e;
        return false;
      }
    } else {
      EnvMapResult env = read_env_map(a.env_path);
      if (!env.ok()) {
        error = env.error;
        return false;
      }
      request.environment =
          std::make_shared<const Environment>(Environment::equirect(env.radiance_rgb, env_settings));
    }
  } else if (!a.sky.empty()) {
    SkyGradient sky;
    if (!parse_sky(a.sky, sky.top, sky.bottom, error)) return false;
    if (build_environment) request.environment = std::make_shared<const Environment>(Environment::sky(sky, env_settings));
  } else if (a.env_constant > 0 && build_environment) {
    request.environment =
        std::make_shared<const Environment>(Environment::constant(glm::vec3(a.env_constant), env_settings));
  }

  if (!a.composite.empty() && !parse_composite(a.composite, request.composite_terms, error)) return false;
  return true;
}

}  // namespace ssdo
