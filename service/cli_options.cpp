#include "service/cli_options.h"

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
  if (with_terms)
    app.add_option("--terms", a.terms, "Terms to compute and write: ao, ssdo, composite, all")
        ->capture_default_str()
        ->group("Compute");
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

bool resolve_compute_options(const ComputeOptionArgs& a, FrameRequest& request, std::string& error) {
  const auto method = parse_ao_method(a.method);
  const auto preset = parse_preset(a.preset);
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
  return true;
}

}  // namespace ssdo
