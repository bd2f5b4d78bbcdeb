// ssdo info: what each frame holds and how it will be read. Reads every frame fully (the
// depth range and the masked / non-finite counts need the pixels), prints text or JSON.
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "service/cli_options.h"
#include "service/commands.h"
#include "service/frame_inputs.h"

namespace ssdo {

namespace {

nlohmann::json info_json(const ReadResult& r) {
  const FrameInfo& i = r.info;
  nlohmann::json j;
  j["path"] = i.path;
  if (!r.ok()) {
    j["error"] = r.error;
    return j;
  }
  j["width"] = i.width_px;
  j["height"] = i.height_px;
  j["data_window"] = {{"x", i.data_x}, {"y", i.data_y}, {"width", i.width_px},
                      {"height", i.height_px}};
  j["display_window"] = {{"x", i.display_x}, {"y", i.display_y}, {"width", i.display_width_px},
                         {"height", i.display_height_px}};
  j["parts"] = i.parts;
  j["part"] = i.part;
  j["channels"] = i.channels;
  j["profile"] = i.profile;
  if (!i.layer.empty()) j["layer"] = i.layer;
  nlohmann::json uses = nlohmann::json::array();
  for (const auto& u : i.uses) {
    nlohmann::json e = {{"input", u.input}, {"channels", u.channels}};
    if (!u.space.empty()) e["space"] = u.space;
    uses.push_back(e);
  }
  j["uses"] = uses;
  j["normals_reconstructed"] = i.normals_reconstructed;
  j["camera"] = {{"source", i.camera_source}, {"near", i.near_view}, {"far", i.far_view},
                 {"perspective", r.gbuffer.camera.is_perspective()}};
  if (r.gbuffer.camera.is_perspective()) {
    j["camera"]["fov_x_deg"] = i.fov_x_deg;
    j["camera"]["fov_y_deg"] = i.fov_y_deg;
  } else {
    j["camera"]["view_width"] = i.view_width;
    j["camera"]["view_height"] = i.view_height;
  }
  j["depth_kind"] = i.depth_kind;
  if (!i.back_layer.empty()) j["back_layer"] = i.back_layer;
  if (i.ao_distance_world) j["ao_distance"] = *i.ao_distance_world;
  if (i.foreground_pixels > 0) {
    j["depth_range"] = {i.depth_min_view, i.depth_max_view};  // planar, as the terms use it
    j["depth_range_stored"] = {i.depth_min_stored, i.depth_max_stored};  // as the file holds it
  }
  j["foreground_pixels"] = i.foreground_pixels;
  j["masked_pixels"] = i.masked_pixels;
  j["nonfinite_pixels"] = i.nonfinite_pixels;
  j["repaired_normal_pixels"] = i.repaired_normal_pixels;
  j["normals_facing_away_pixels"] = i.normals_facing_away_pixels;
  j["notes"] = i.notes;
  return j;
}

std::string info_text(const ReadResult& r) {
  const FrameInfo& i = r.info;
  std::ostringstream s;
  s << i.path << "\n";
  s << "  resolution     " << i.width_px << " x " << i.height_px << " (data window at ("
    << i.data_x << ", " << i.data_y << "); display window " << i.display_width_px << " x "
    << i.display_height_px << " at (" << i.display_x << ", " << i.display_y << "))\n";
  if (i.parts.size() > 1) {
    s << "  parts          ";
    for (size_t k = 0; k < i.parts.size(); ++k) s << (k ? ", " : "") << i.parts[k];
    s << "\n  read from part " << i.part << "\n";
  }
  s << "  channels       " << i.channels.size() << ":";
  for (const auto& c : i.channels) s << "\n                   " << c;
  s << "\n  profile        " << i.profile;
  if (!i.layer.empty()) s << " (layer " << i.layer << ")";
  s << "\n  inputs\n";
  for (const auto& u : i.uses) {
    s << "    " << u.input << std::string(u.input.size() < 18 ? 18 - u.input.size() : 1, ' ')
      << u.channels;
    if (!u.space.empty()) s << "  [" << u.space << " space]";
    s << "\n";
  }
  if (i.normals_reconstructed) s << "    normal            reconstructed from depth\n";
  char buf[256];
  if (r.gbuffer.camera.is_perspective())
    std::snprintf(buf, sizeof buf, "  camera         %s\n                 fov %.3f x %.3f deg, ",
                  i.camera_source.c_str(), i.fov_x_deg, i.fov_y_deg);
  else
    std::snprintf(buf, sizeof buf, "  camera         %s\n                 orthographic, %.4g x %.4g scene units, ",
                  i.camera_source.c_str(), i.view_width, i.view_height);
  s << buf;
  if (i.near_view > 0 || i.far_view > 0)
    s << "near " << i.near_view << ", far " << i.far_view << "\n";
  else
    s << "near/far unknown\n";
  s << "  depth          " << i.depth_kind;
  if (i.depth_kind == "radial") {
    s << " (distance from the eye), converted to planar";
    if (i.foreground_pixels > 0)
      s << "; foreground range " << i.depth_min_stored << " .. " << i.depth_max_stored << " as stored (radial), "
        << i.depth_min_view << " .. " << i.depth_max_view << " planar";
  } else if (i.foreground_pixels > 0) {
    s << ", foreground range " << i.depth_min_view << " .. " << i.depth_max_view;
  }
  s << "\n";
  if (!i.back_layer.empty()) s << "  back layer     " << i.back_layer << "\n";
  if (i.ao_distance_world) s << "  AO distance    " << *i.ao_distance_world << "\n";
  s << "  pixels         " << i.foreground_pixels << " foreground, " << i.masked_pixels
    << " masked (" << i.nonfinite_pixels << " non-finite)";
  if (i.repaired_normal_pixels) s << ", " << i.repaired_normal_pixels << " zero normals rebuilt";
  s << "\n";
  for (const auto& n : i.notes) s << "  note           " << n << "\n";
  return s.str();
}

}  // namespace

int run_info(const InfoArgs& args) {
  int status = 0;
  nlohmann::json all = nlohmann::json::array();
  for (const auto& file : args.files) {
    ReadResult r = read_frame(file, args.read);  // what info reports is what the pipeline computes on
    if (!r.ok()) {
      std::cerr << "error: " << r.error << "\n";
      status = 1;
    }
    if (args.json)
      all.push_back(info_json(r));
    else if (r.ok())
      std::cout << info_text(r);
  }
  // Names that are not UTF-8 (file and channel names are bytes) come out with U+FFFD.
  if (args.json) std::cout << all.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  return status;
}

Command register_info(CLI::App& app) {
  auto st = std::make_shared<CommandState<InfoArgs>>();
  CLI::App* cmd = app.add_subcommand(
      "info", "Print what a frame holds: resolution, parts, channels, detected profile, which "
              "channel becomes which input, camera and its source, depth range, masked pixels");
  cmd->add_option("files", st->args.files, "EXR frames")->required();
  cmd->add_flag("--json", st->args.json, "Print JSON instead of text");
  add_frame_options(*cmd, st->options, int(OptionSet::read));
  return {cmd, [st] {
            std::string error;
            if (!resolve_read_options(st->options.read, st->args.read, error)) return usage_error(error);
            return run_info(st->args);
          }};
}

}  // namespace ssdo
