// Every frame option, declared once. A frame option is a value that decides one frame's
// output; it is spelled the same everywhere: `--NAME VALUE` on the command line, "NAME":
// VALUE in a --config file, in a socket request's "options" and in a worker request.
// The command line's options and validators (cli_options.cpp), the JSON schema (to_json,
// apply_json in request_options.cpp) and the options reference (docs/options.md, printed
// by `ssdo options --markdown`) are all derived from the table frame_options().
//
// The ranges here are the user-facing check, made once at the boundary; the kernels'
// validate() functions keep their own invariants, and the table's ranges lie inside them
// (tested at both ends of every range).
#pragma once

#include <string>
#include <variant>
#include <vector>

namespace ssdo {

// --views when not given: neighbouring frames used on each side of a frame as extra views
// (0 = every frame alone).
inline constexpr int kDefaultViewsPerSide = 2;

// --temporal when not given: a frame of a sequence has its denoised terms filtered over 2
// frames on each side, the K the measurements chose (docs/temporal.md;
// tests/accuracy/temporal_accuracy_test.cpp): flicker divided by 3 to 4 for gtao medium and
// by 2.4 to 3.5 for SSDO's terms, where K = 1 is just above 2x. 0 is a frame alone, bit for bit.
inline constexpr int kDefaultTemporalPerSide = 2;

// The largest radiance an option may give the environment (--env-constant, --sky): the
// largest half float, since the outputs store radiance in half (more would be inf there).
inline constexpr float kMaxRadiance = 65504.0f;

// Raw option values as typed; resolved into a request by resolve_* (cli_options.h).
struct ReadOptionArgs {
  std::vector<std::string> maps;  // --map input=channel
  std::string camera_json;
  float fov_x_deg = 0;            // 0 = unset
  std::string depth_kind = "auto";
  std::string part;
};

struct ComputeOptionArgs {
  std::string method = "gtao";
  std::string preset = "medium";
  float radius_world = 0;  // 0 = preset / frame default
  float thickness_world = 0;
  std::string thickness_model;  // "" (the preset's) | constant (thickness_world) | silhouettes
  int threads = 0;
  std::string terms = "ao,composite";
  bool multibounce = false;       // AO: Jimenez et al. 2016's multi-bounce fit with the albedo
  // SSDO and the environment
  std::string ssdo_method = "ssdo";
  std::string ssdo_preset;        // empty = --preset
  std::string env_path;           // equirect radiance map
  std::string sky;                // "TOP,BOTTOM" two-colour sky
  float env_constant = 0;         // uniform radiance (0 = unset)
  std::string env_up = "z";
  std::string composite;          // mode or weighted term list
  // --quality auto --max-error E: method and preset from the shipped calibration table
  std::string quality;            // "" (method/preset as given) or "auto"
  float max_error = 0.05f;        // MAE against ray-traced AO, for --quality auto
  int views = kDefaultViewsPerSide;  // neighbouring frames per side as extra views
  int temporal = kDefaultTemporalPerSide;  // neighbouring frames per side of the temporal filter
};

// Everything that decides one frame's output, as typed (strings and numbers).
struct FrameOptionArgs {
  ReadOptionArgs read;
  ComputeOptionArgs compute;
  std::string compression = "zip";  // zip | zips | piz | rle | none | dwaa
  bool png = false;                  // sRGB PNG previews beside the EXR
  bool io_only = false;              // read and write as the terms would, compute nothing
  int guard_band_px = 0;             // pixels cropped off each side of every output
};

enum class OptionKind {
  text,     // any string
  choice,   // one of `choices`
  number,   // a float in [lo, hi] (hi = infinity: any finite number from lo)
  integer,  // an int in [lo, hi]
  flag,     // true or false
  list,     // strings; the command line repeats the flag, JSON takes a list or one string
};

// Which commands take an option: reading (info, bench, eval, process, serve, client),
// computing (eval, process, serve, client), writing (process, serve, client).
enum class OptionSet { read = 1, compute = 2, output = 4 };
inline constexpr int kAllOptionSets = 1 | 2 | 4;

// Where an option's value lives in FrameOptionArgs (a captureless lambda per option).
template <class T>
using OptionField = T& (*)(FrameOptionArgs&);
using OptionFieldRef = std::variant<OptionField<std::string>, OptionField<float>, OptionField<int>,
                                    OptionField<bool>, OptionField<std::vector<std::string>>>;

struct FrameOption {
  const char* name;      // command-line flag without "--" = JSON key
  OptionKind kind;
  OptionSet set;
  const char* group;     // heading in --help and docs/options.md
  const char* help;
  const char* unset = "";  // what the default value (0, "") means, when it is a placeholder
  std::vector<std::string> choices = {};  // choice; "" among them = may be left unset
  double lo = 0, hi = 0;   // number, integer: inclusive range
  bool zero_unset = false;  // number: 0 = unset, accepted besides [lo, hi]
  bool file = false;           // text: names a file (a client sends it as its own path)
  bool existing_file = false;  // the command line checks that the file exists
  OptionFieldRef field = {};
};

// The table, in the order of --help and of the JSON keys.
const std::vector<FrameOption>& frame_options();
// The entry of `name` (a JSON key), or null.
const FrameOption* find_frame_option(const std::string& name);

// Empty when `value` is acceptable for `option` (a choice, or a number or integer of its
// range); else what it must be, without the key, e.g. "must be a number in [0, 1]" or
// "'x' is not one of a, b".
std::string check_choice(const FrameOption& option, const std::string& value);
std::string check_number(const FrameOption& option, double value);

// A number as a user writes it: 30, 0.5, 1e+10, inf (six significant digits).
std::string number_text(double v);

// The range as written in messages and docs: "[0.1, 179.9]", "[0, inf)".
std::string describe_range(const FrameOption& option);

// The options reference: one Markdown table per group (name, type, default, meaning).
std::string frame_options_markdown();

}  // namespace ssdo
