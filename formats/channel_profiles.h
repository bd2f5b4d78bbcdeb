// Which EXR channels become which G-buffer input: profile detection ("blender",
// "generic") and explicit mappings. Pure name matching, no file access, so it is shared by
// read_gbuffer and inspect_gbuffer and testable on channel lists.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "formats/gbuffer_reader.h"

namespace ssdo {

// The channels of one part of a file.
struct PartChannels {
  std::string name;                 // part name ("" for a single-part file without one)
  std::vector<std::string> channels;  // as stored (sorted by name)
};

// One input resolved to channels: 1 (depth, AO) or 3 (x y z / R G B, in that order).
struct ResolvedInput {
  std::string input;                  // "depth", "normal", "position", "albedo", "lighting",
                                      // "diffdir" (lighting factor), "reference:NAME"
  std::vector<std::string> channels;  // full channel names
  int part = 0;                       // index into the parts list
  Space space = Space::automatic;     // for normal / position
  // "ViewLayer.Normal.{X,Y,Z}" style summary for reports.
  std::string describe() const;
};

struct ChannelResolution {
  std::string profile;  // "blender" | "generic" | "mapping" ("" = no depth found)
  std::string layer;    // blender layer prefix
  std::vector<std::string> layers;  // every blender view layer of the depth part (layer among them)
  int part = 0;         // the part depth comes from
  std::vector<ResolvedInput> inputs;  // depth first when found
  const ResolvedInput* find(const std::string& input) const;
};

// Resolves every input the options ask for. The part holding depth is options.part (by
// name) or the first part in which a profile (or the mapping) finds depth; the other
// inputs are looked up in that part first, then in the other parts in file order.
// Returns an error message (naming what is missing and the channels present) when
// options.part names no part, when a mapped channel does not exist, or when no depth is
// found; `path` only names the file in messages.
std::optional<ChannelResolution> resolve_channels(const std::string& path,
                                                  const std::vector<PartChannels>& parts,
                                                  const ReadOptions& options,
                                                  std::string* error);

// "a, b, c" (at most `limit` names, then "... (N more)").
std::string join_names(const std::vector<std::string>& names, size_t limit = 64);

}  // namespace ssdo
