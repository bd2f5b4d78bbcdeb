#include "service/request_options.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace ssdo {

namespace {

using json = nlohmann::json;

bool one_of(const std::string& v, std::initializer_list<const char*> set) {
  return std::any_of(set.begin(), set.end(), [&](const char* s) { return v == s; });
}

std::string list(std::initializer_list<const char*> set) {
  std::string s;
  for (const char* v : set) s += (s.empty() ? "" : ", ") + std::string(v);
  return s;
}

bool get_string(const json& v, const std::string& key, std::string& out, std::string& error) {
  if (!v.is_string()) {
    error = "\"" + key + "\" must be a string";
    return false;
  }
  out = v.get<std::string>();
  return true;
}

bool get_choice(const json& v, const std::string& key, std::initializer_list<const char*> set, std::string& out,
                std::string& error) {
  std::string s;
  if (!get_string(v, key, s, error)) return false;
  if (!one_of(s, set)) {
    error = "\"" + key + "\": '" + s + "' is not one of " + list(set);
    return false;
  }
  out = s;
  return true;
}

// A number in [lo, hi] (inclusive).
bool get_number(const json& v, const std::string& key, double lo, double hi, float& out, std::string& error) {
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi) {
    std::ostringstream s;
    s << "\"" << key << "\" must be a number in [" << lo << ", " << hi << "]";
    error = s.str();
    return false;
  }
  out = v.get<float>();
  return true;
}

}  // namespace

const std::vector<std::string>& frame_option_keys() {
  static const std::vector<std::string> keys = {
      "map",  "camera", "fov",      "depth-kind",  "part",        "method", "preset",       "radius",
      "thickness", "threads", "terms", "ssdo-method", "ssdo-preset", "env",    "sky", "env-constant",
      "env-up", "composite", "compression", "png", "quality", "max-error", "io-only"};
  return keys;
}

json to_json(const FrameOptionArgs& a) {
  const ReadOptionArgs& r = a.read;
  const ComputeOptionArgs& c = a.compute;
  return json{{"map", r.maps},
              {"camera", r.camera_json},
              {"fov", r.fov_x_deg},
              {"depth-kind", r.depth_kind},
              {"part", r.part},
              {"method", c.method},
              {"preset", c.preset},
              {"radius", c.radius_world},
              {"thickness", c.thickness_world},
              {"threads", c.threads},
              {"terms", c.terms},
              {"ssdo-method", c.ssdo_method},
              {"ssdo-preset", c.ssdo_preset},
              {"env", c.env_path},
              {"sky", c.sky},
              {"env-constant", c.env_constant},
              {"env-up", c.env_up},
              {"composite", c.composite},
              {"quality", c.quality},
              {"max-error", c.max_error},
              {"compression", a.compression},
              {"png", a.png},
              {"io-only", a.io_only}};
}

json to_json(const FrameOptionArgs& a, const std::function<bool(const std::string&)>& given) {
  json all = to_json(a), some = json::object();
  for (const std::string& key : frame_option_keys())
    if (given(key)) some[key] = all[key];
  return some;
}

bool apply_json(const json& j, FrameOptionArgs& a, std::string& error,
                const std::function<bool(const std::string&)>& keep) {
  if (!j.is_object()) {
    error = "options must be a JSON object";
    return false;
  }
  ReadOptionArgs& r = a.read;
  ComputeOptionArgs& c = a.compute;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    const json& v = it.value();
    const auto& keys = frame_option_keys();
    if (std::find(keys.begin(), keys.end(), k) == keys.end()) {
      error = "unknown option \"" + k + "\" (known: " + [&] {
        std::string s;
        for (const auto& key : keys) s += (s.empty() ? "" : ", ") + key;
        return s;
      }() + ")";
      return false;
    }
    if (keep && keep(k)) continue;
    bool ok = true;
    if (k == "map") {
      // A list of INPUT=CHANNEL strings, or one such string.
      std::vector<std::string> maps;
      if (v.is_string()) {
        maps.push_back(v.get<std::string>());
      } else if (v.is_array() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_string(); })) {
        maps = v.get<std::vector<std::string>>();
      } else {
        error = "\"map\" must be a list of INPUT=CHANNEL strings";
        return false;
      }
      r.maps = maps;
    } else if (k == "camera") ok = get_string(v, k, r.camera_json, error);
    else if (k == "fov") {
      // 0 = unset, as on the command line's default.
      ok = get_number(v, k, 0, 179.9, r.fov_x_deg, error);
      if (ok && r.fov_x_deg > 0 && r.fov_x_deg < 0.1f) {
        error = "\"fov\" must be 0 (unset) or in [0.1, 179.9] degrees";
        ok = false;
      }
    } else if (k == "depth-kind") ok = get_choice(v, k, {"auto", "planar", "radial"}, r.depth_kind, error);
    else if (k == "part") ok = get_string(v, k, r.part, error);
    else if (k == "method") ok = get_choice(v, k, {"hemisphere", "hbao", "gtao", "raymarch"}, c.method, error);
    else if (k == "preset") ok = get_choice(v, k, {"low", "medium", "high", "ultra"}, c.preset, error);
    else if (k == "radius") ok = get_number(v, k, 0, 1e30, c.radius_world, error);
    else if (k == "thickness") ok = get_number(v, k, 0, 1e30, c.thickness_world, error);
    else if (k == "threads") {
      float t = 0;
      ok = get_number(v, k, 0, 1024, t, error);
      if (ok && (!v.is_number_integer())) {
        error = "\"threads\" must be an integer in [0, 1024]";
        ok = false;
      }
      c.threads = int(t);
    } else if (k == "terms") ok = get_string(v, k, c.terms, error);
    else if (k == "ssdo-method") ok = get_choice(v, k, {"ssdo", "oracle"}, c.ssdo_method, error);
    else if (k == "ssdo-preset") {
      std::string s;
      ok = get_string(v, k, s, error);
      if (ok && !s.empty() && !one_of(s, {"low", "medium", "high", "ultra"})) {
        error = "\"ssdo-preset\": '" + s + "' is not one of low, medium, high, ultra";
        ok = false;
      }
      if (ok) c.ssdo_preset = s;
    } else if (k == "env") ok = get_string(v, k, c.env_path, error);
    else if (k == "sky") ok = get_string(v, k, c.sky, error);
    else if (k == "env-constant") ok = get_number(v, k, 0, 1e30, c.env_constant, error);
    else if (k == "env-up") ok = get_choice(v, k, {"z", "y"}, c.env_up, error);
    else if (k == "composite") ok = get_string(v, k, c.composite, error);
    else if (k == "quality") {
      std::string q;
      ok = get_string(v, k, q, error);
      if (ok && !q.empty() && q != "auto") {
        error = "\"quality\": '" + q + "' is not auto";
        ok = false;
      }
      if (ok) c.quality = q;
    } else if (k == "max-error") ok = get_number(v, k, 0, 1, c.max_error, error);
    else if (k == "compression")
      ok = get_choice(v, k, {"zip", "zips", "piz", "rle", "none", "dwaa"}, a.compression, error);
    else if (k == "png" || k == "io-only") {
      if (!v.is_boolean()) {
        error = "\"" + k + "\" must be true or false";
        ok = false;
      } else {
        (k == "png" ? a.png : a.io_only) = v.get<bool>();
      }
    }
    if (!ok) return false;
  }
  return true;
}

bool load_json_file(const std::string& path, json& j, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for numbers like 1e309
    error = path + ": not valid JSON: " + e.what();
    return false;
  }
  if (!j.is_object()) {
    error = path + ": expected a JSON object of options";
    return false;
  }
  return true;
}

bool resolve_frame_options(const FrameOptionArgs& a, FrameRequest& request, std::string& error,
                           bool build_environment) {
  if (!resolve_read_options(a.read, request.read, error) ||
      !resolve_compute_options(a.compute, request, error, build_environment))
    return false;
  request.write.compression = a.compression;
  request.write.png_previews = a.png;
  request.io_only = a.io_only;
  return true;
}

std::vector<std::string> option_paths(const FrameOptionArgs& a) {
  std::vector<std::string> paths;
  if (!a.read.camera_json.empty()) paths.push_back(a.read.camera_json);
  if (!a.compute.env_path.empty()) paths.push_back(a.compute.env_path);
  return paths;
}

}  // namespace ssdo
