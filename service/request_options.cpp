#include "service/request_options.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <type_traits>
#include <variant>

#include "service/frame_options.h"
#include "service/version.h"

namespace ssdo {

namespace {

using json = nlohmann::json;

std::string quoted(const FrameOption& o) { return "\"" + std::string(o.name) + "\""; }

// A JSON value for a text or choice option.
bool get_text(const json& v, const FrameOption& o, std::string& out, std::string& error) {
  if (!v.is_string()) {
    error = quoted(o) + " must be a string";
    return false;
  }
  const std::string s = v.get<std::string>();
  // A path with a NUL names another file to the system than the one checked and reported.
  if (s.find('\0') != std::string::npos) {
    error = quoted(o) + " holds a NUL byte";
    return false;
  }
  if (o.kind == OptionKind::choice) {
    if (std::string e = check_choice(o, s); !e.empty()) {
      error = quoted(o) + ": " + e;
      return false;
    }
  }
  out = s;
  return true;
}

// A JSON value for a number or integer option, within the option's range.
template <class T>
bool get_number(const json& v, const FrameOption& o, T& out, std::string& error) {
  // An integer option takes a JSON integer only (not 3.0), as the command line takes "3".
  const bool typed = v.is_number() && (o.kind != OptionKind::integer || !v.is_number_float());
  if (const std::string e = check_number(o, typed ? v.get<double>() : NAN); !e.empty()) {
    error = quoted(o) + " " + e;
    return false;
  }
  out = v.get<T>();
  return true;
}

bool get_flag(const json& v, const FrameOption& o, bool& out, std::string& error) {
  if (!v.is_boolean()) {
    error = quoted(o) + " must be true or false";
    return false;
  }
  out = v.get<bool>();
  return true;
}

// A list of strings, or one string (a list of one).
bool get_list(const json& v, const FrameOption& o, std::vector<std::string>& out, std::string& error) {
  if (v.is_string()) {
    out = {v.get<std::string>()};
  } else if (v.is_array() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_string(); })) {
    out = v.get<std::vector<std::string>>();
  } else {
    error = quoted(o) + " must be a list of strings" + (std::string(o.name) == "map" ? " INPUT=CHANNEL" : "");
    return false;
  }
  if (std::any_of(out.begin(), out.end(), [](const std::string& e) { return e.find('\0') != std::string::npos; })) {
    error = quoted(o) + " holds a NUL byte";
    return false;
  }
  return true;
}

bool get_value(const json& v, const FrameOption& o, FrameOptionArgs& a, std::string& error) {
  return std::visit(
      [&](auto field) {
        auto& out = field(a);
        using T = std::decay_t<decltype(out)>;
        if constexpr (std::is_same_v<T, std::string>) return get_text(v, o, out, error);
        else if constexpr (std::is_same_v<T, bool>) return get_flag(v, o, out, error);
        else if constexpr (std::is_same_v<T, std::vector<std::string>>) return get_list(v, o, out, error);
        else return get_number(v, o, out, error);
      },
      o.field);
}

std::string known_keys() {
  std::string s;
  for (const std::string& key : frame_option_keys()) s += (s.empty() ? "" : ", ") + key;
  return s;
}

}  // namespace

const std::vector<std::string>& frame_option_keys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const FrameOption& o : frame_options()) k.push_back(o.name);
    return k;
  }();
  return keys;
}

json to_json(const FrameOptionArgs& a) {
  FrameOptionArgs& values = const_cast<FrameOptionArgs&>(a);  // the fields are only read
  json j = json::object();
  for (const FrameOption& o : frame_options())
    std::visit([&](auto field) { j[o.name] = field(values); }, o.field);
  return j;
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
  for (auto it = j.begin(); it != j.end(); ++it) {
    const FrameOption* o = find_frame_option(it.key());
    if (o == nullptr) {
      error = "unknown option \"" + it.key() + "\" (known: " + known_keys() + ")";
      return false;
    }
    if (keep && keep(it.key())) continue;
    if (!get_value(it.value(), *o, a, error)) return false;
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
  // DWAA quantises in a perceptual colour space: only the composite (a picture) may be
  // stored with it, and every AO or SSDO output also writes numeric and vector terms.
  if (a.compression == "dwaa" && (request.terms.ao || request.terms.ssdo)) {
    error = "--compression dwaa is lossy and only for colour terms: with --terms ao or ssdo the outputs hold "
            "numeric and vector terms (AO, bent normal, confidence); use zip or piz, or --terms composite";
    return false;
  }
  request.write.compression = a.compression;
  request.write.png_previews = a.png;
  request.write.string_attributes = output_attributes(a);
  request.io_only = a.io_only;
  request.guard_band_px = a.guard_band_px;
  return true;
}

std::string options_attribute(const FrameOptionArgs& given) {
  // Every option but "threads": outputs are the same bytes for any thread count, and so
  // are their headers. Options that change nothing with the others are recorded as their
  // defaults, so that such a value does not make outputs stale: --max-error without
  // --quality auto, --composite when no composite is written.
  FrameOptionArgs a = given;
  if (a.compute.quality != "auto") a.compute.max_error = ComputeOptionArgs{}.max_error;
  TermSelection terms;
  if (std::string error; parse_terms(a.compute.terms, terms, error) && !terms.composite) a.compute.composite.clear();
  const json options = to_json(a, [](const std::string& key) { return key != "threads"; });
  return options.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::vector<std::pair<std::string, std::string>> output_attributes(const FrameOptionArgs& a) {
  return {{kVersionAttribute, version_string()}, {kOptionsAttribute, options_attribute(a)}};
}

std::vector<std::string> option_paths(const FrameOptionArgs& a) {
  std::vector<std::string> paths;
  if (!a.read.camera_json.empty()) paths.push_back(a.read.camera_json);
  if (!a.compute.env_path.empty()) paths.push_back(a.compute.env_path);
  return paths;
}

}  // namespace ssdo
