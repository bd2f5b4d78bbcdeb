#include "formats/channel_profiles.h"

#include <algorithm>

namespace ssdo {

namespace {

// Component suffixes tried for a 3-vector layer, in order of preference.
const std::vector<std::vector<std::string>> kVectorSuffixes = {
    {"X", "Y", "Z"}, {"R", "G", "B"}, {"x", "y", "z"}, {"r", "g", "b"}};
// Component suffixes tried for a 1-channel layer named by its prefix ("depth" -> depth.Z).
const std::vector<std::string> kScalarSuffixes = {"Z", "z", "R", "r", "Y", "y", "V", "v"};

bool has(const PartChannels& p, const std::string& name) {
  return std::find(p.channels.begin(), p.channels.end(), name) != p.channels.end();
}

// Part indices to search: `preferred` first, then the others in file order.
std::vector<int> search_order(int n_parts, int preferred) {
  std::vector<int> order{preferred};
  for (int i = 0; i < n_parts; ++i)
    if (i != preferred) order.push_back(i);
  return order;
}

std::optional<ResolvedInput> find_scalar(const std::vector<PartChannels>& parts, int preferred,
                                         const std::string& input, const std::string& name,
                                         bool allow_suffix) {
  for (int p : search_order(int(parts.size()), preferred)) {
    if (has(parts[p], name)) return ResolvedInput{input, {name}, p, Space::automatic};
    if (!allow_suffix) continue;
    for (const auto& s : kScalarSuffixes)
      if (has(parts[p], name + "." + s))
        return ResolvedInput{input, {name + "." + s}, p, Space::automatic};
  }
  return std::nullopt;
}

std::optional<ResolvedInput> find_vector(const std::vector<PartChannels>& parts, int preferred,
                                         const std::string& input, const std::string& prefix,
                                         Space space = Space::automatic) {
  for (int p : search_order(int(parts.size()), preferred)) {
    for (const auto& suffixes : kVectorSuffixes) {
      std::vector<std::string> names;
      for (const auto& s : suffixes) names.push_back(prefix.empty() ? s : prefix + "." + s);
      if (std::all_of(names.begin(), names.end(),
                      [&](const std::string& n) { return has(parts[p], n); }))
        return ResolvedInput{input, names, p, space};
    }
  }
  return std::nullopt;
}

// Blender view layer prefixes of a part's "<Layer>.Depth.Z" channels, in channel order.
std::vector<std::string> blender_layers(const PartChannels& p) {
  const std::string suffix = ".Depth.Z";
  std::vector<std::string> layers;
  for (const auto& c : p.channels)
    if (c.size() > suffix.size() && c.compare(c.size() - suffix.size(), suffix.size(), suffix) == 0)
      layers.push_back(c.substr(0, c.size() - suffix.size()));
  return layers;
}

// The view layer the inputs come from: the one whose depth the mapping names
// ("<Layer>.Depth.Z" or "<Layer>.Depth"), else the first.
std::optional<std::string> blender_layer(const PartChannels& p, const ChannelMapping& map = {}) {
  const std::vector<std::string> layers = blender_layers(p);
  for (const std::string& layer : layers)
    if (map.depth == layer + ".Depth.Z" || map.depth == layer + ".Depth") return layer;
  if (layers.empty()) return std::nullopt;
  return layers.front();
}

std::optional<std::string> generic_depth(const PartChannels& p) {
  for (const char* name : {"Z", "depth.Z"})
    if (has(p, name)) return std::string(name);
  return std::nullopt;
}

// Flat channels a renderer would write a back-face depth pass to (an AOV of the depth of
// the nearest back face, e.g. a second render with front faces culled). No renderer we
// know has a standard name for it. "ZBack" is not one of them: in a deep image it is
// each sample's back (OpenEXR, "Interpreting OpenEXR Deep Pixels"), not a second surface.
const std::vector<std::string> kGenericBackDepth = {"Z.back", "depth_back"};

// Whether the mapping names a channel (else at most spaces, for the detected channels).
bool maps_channels(const ChannelMapping& m) {
  return !(m.depth.empty() && m.depth_back.empty() && m.normal.empty() && m.position.empty() &&
           m.albedo.empty() && m.lighting.empty() && m.references.empty());
}

bool mapping_is_empty(const ChannelMapping& m) {
  return !maps_channels(m) && m.normal_space == Space::automatic && m.position_space == Space::automatic;
}

// " (part "NAME")" in a multi-part file, else "".
std::string part_label(const std::vector<PartChannels>& parts, int p) {
  return parts.size() == 1 ? std::string() : " (part \"" + parts[p].name + "\")";
}

// The part holding depth: options.part by name, else the first part in which the mapping
// or a profile finds depth, else the first part; nullopt when options.part names no part.
std::optional<int> depth_part(const std::string& path, const std::vector<PartChannels>& parts,
                              const ReadOptions& options, std::string* error) {
  const ChannelMapping& map = options.mapping;
  if (!options.part.empty()) {
    for (size_t i = 0; i < parts.size(); ++i)
      if (parts[i].name == options.part) return int(i);
    std::vector<std::string> names;
    for (const auto& p : parts) names.push_back("\"" + p.name + "\"");
    *error = path + ": no part named \"" + options.part + "\"; parts: " + join_names(names);
    return std::nullopt;
  }
  for (size_t i = 0; i < parts.size(); ++i) {
    const bool found = !map.depth.empty()
                           ? find_scalar({parts[i]}, 0, "depth", map.depth, true).has_value()
                           : blender_layer(parts[i]) || generic_depth(parts[i]);
    if (found) return int(i);
  }
  return 0;
}

// The inputs a profile finds from the depth part `part`: "blender" (a <Layer>.Depth.Z
// channel; of several view layers, the one whose depth the mapping names, else the
// first) or "generic" (Z or depth.Z); neither leaves `res` empty. A back-face depth
// ("depth_back") is <Layer>.DepthBack (an AOV) or Z.back / depth_back.
void detect_profile(const std::vector<PartChannels>& parts, int part, const ChannelMapping& map,
                    ChannelResolution& res) {
  const PartChannels& pc = parts[part];
  auto add = [&](std::optional<ResolvedInput> r) {
    if (r) res.inputs.push_back(*r);
    return r.has_value();
  };
  if (auto layer = blender_layer(pc, map)) {
    res.profile = "blender";
    res.layer = *layer;
    res.layers = blender_layers(pc);
    const std::string L = *layer + ".";
    res.inputs.push_back({"depth", {L + "Depth.Z"}, part, Space::automatic});
    add(find_vector(parts, part, "normal", L + "Normal", Space::world));
    add(find_vector(parts, part, "position", L + "Position", Space::world));
    add(find_vector(parts, part, "albedo", L + "DiffCol"));
    add(find_vector(parts, part, "diffdir", L + "DiffDir"));
    add(find_scalar(parts, part, "depth_back", L + "DepthBack", true));
    add(find_scalar(parts, part, "reference:AO", L + "AO.R", false));
    for (const char* name : {"DiffDir", "DiffInd"})
      add(find_vector(parts, part, std::string("reference:") + name, L + name));
  } else if (auto depth = generic_depth(pc)) {
    res.profile = "generic";
    res.inputs.push_back({"depth", {*depth}, part, Space::automatic});
    add(find_vector(parts, part, "normal", "N"));
    add(find_vector(parts, part, "position", "P"));
    for (const char* name : {"albedo", "diffuse_albedo"})
      if (add(find_vector(parts, part, "albedo", name))) break;
    for (const std::string& name : kGenericBackDepth)
      if (add(find_scalar(parts, part, "depth_back", name, true))) break;
  }
}

// Replaces the inputs an explicit mapping names; a named channel or layer that does not
// exist is an error listing the channels present.
struct MappingApplier {
  const std::string& path;
  const std::vector<PartChannels>& parts;
  int part;
  ChannelResolution& res;
  std::string* error;

  std::string all_channels() const {
    std::vector<std::string> all;
    for (size_t i = 0; i < parts.size(); ++i)
      for (const auto& c : parts[i].channels)
        all.push_back(parts.size() == 1 ? c : parts[i].name + ":" + c);
    return join_names(all);
  }
  void replace(const ResolvedInput& r) {
    std::erase_if(res.inputs, [&](const ResolvedInput& x) { return x.input == r.input; });
    res.inputs.push_back(r);
  }
  bool scalar(const std::string& input, const std::string& name) {
    auto r = find_scalar(parts, part, input, name, true);
    if (!r) {
      *error = path + part_label(parts, part) + ": mapped " + input + " channel \"" + name +
               "\" not found (tried " + name + " and " + name + ".{Z,R,Y,V}); channels present: " +
               all_channels();
      return false;
    }
    replace(*r);
    return true;
  }
  bool vector(const std::string& input, const std::string& name, Space space) {
    auto r = find_vector(parts, part, input, name, space);
    // Mapped to the very channels the profile found (--map normal=ViewLayer.Normal): the
    // space the profile knows them in stays, unless the mapping states one.
    const ResolvedInput* found = res.find(input);
    if (r && found && space == Space::automatic && found->channels == r->channels) r->space = found->space;
    if (!r) {
      *error = path + part_label(parts, part) + ": mapped " + input + " layer \"" + name +
               "\" not found (tried " + name + ".{X,Y,Z}, .{R,G,B}, .{x,y,z}); channels present: " +
               all_channels();
      return false;
    }
    replace(*r);
    return true;
  }

  bool apply(const ChannelMapping& map) {
    if (maps_channels(map)) res.profile = "mapping";
    if (!map.depth.empty() && !scalar("depth", map.depth)) return false;
    if (!map.depth_back.empty() && !scalar("depth_back", map.depth_back)) return false;
    if (!map.normal.empty() && !vector("normal", map.normal, map.normal_space)) return false;
    if (!map.position.empty() && !vector("position", map.position, map.position_space))
      return false;
    if (!map.albedo.empty() && !vector("albedo", map.albedo, Space::automatic)) return false;
    if (!map.lighting.empty()) {
      if (!vector("lighting", map.lighting, Space::automatic)) return false;
      std::erase_if(res.inputs, [](const ResolvedInput& x) { return x.input == "diffdir"; });
    }
    for (const auto& [name, channel] : map.references) {
      const std::string input = "reference:" + name;
      if (auto r = find_vector(parts, part, input, channel)) {
        replace(*r);
      } else if (!scalar(input, channel)) {
        return false;
      }
    }
    // Explicit spaces apply to detected channels too.
    for (auto& r : res.inputs) {
      if (r.input == "normal" && map.normal_space != Space::automatic) r.space = map.normal_space;
      if (r.input == "position" && map.position_space != Space::automatic)
        r.space = map.position_space;
    }
    return true;
  }
};

}  // namespace

std::string join_names(const std::vector<std::string>& names, size_t limit) {
  std::string s;
  for (size_t i = 0; i < names.size() && i < limit; ++i) {
    if (i) s += ", ";
    s += names[i];
  }
  if (names.size() > limit) s += ", ... (" + std::to_string(names.size() - limit) + " more)";
  return s;
}

std::string ResolvedInput::describe() const {
  if (channels.size() == 1) return channels[0];
  // Common prefix up to the last '.', then the component suffixes in braces.
  const std::string& first = channels[0];
  const size_t dot = first.rfind('.');
  const std::string prefix = dot == std::string::npos ? "" : first.substr(0, dot + 1);
  std::string s = prefix + "{";
  for (size_t i = 0; i < channels.size(); ++i) {
    if (i) s += ',';
    s.append(channels[i], prefix.size(), std::string::npos);
  }
  s += '}';
  return s;
}

const ResolvedInput* ChannelResolution::find(const std::string& input) const {
  for (const auto& r : inputs)
    if (r.input == input) return &r;
  return nullptr;
}

std::optional<ChannelResolution> resolve_channels(const std::string& path,
                                                  const std::vector<PartChannels>& parts,
                                                  const ReadOptions& options,
                                                  std::string* error) {
  if (parts.empty()) {
    *error = path + ": the file has no parts";
    return std::nullopt;
  }
  const std::optional<int> part = depth_part(path, parts, options, error);
  if (!part) return std::nullopt;
  ChannelResolution res;
  res.part = *part;
  detect_profile(parts, *part, options.mapping, res);
  if (!mapping_is_empty(options.mapping) &&
      !MappingApplier{path, parts, *part, res, error}.apply(options.mapping))
    return std::nullopt;
  // Depth is the one required input.
  auto depth = std::find_if(res.inputs.begin(), res.inputs.end(),
                            [](const ResolvedInput& r) { return r.input == "depth"; });
  if (depth == res.inputs.end()) {
    *error = path + part_label(parts, *part) +
             ": required depth channel not found (looked for <Layer>.Depth.Z [blender], "
             "Z or depth.Z [generic]; give one with a channel mapping); channels present: " +
             join_names(parts[*part].channels);
    return std::nullopt;
  }
  res.part = depth->part;  // a mapped depth may live in another part
  std::rotate(res.inputs.begin(), depth, depth + 1);  // depth first
  return res;
}

}  // namespace ssdo
