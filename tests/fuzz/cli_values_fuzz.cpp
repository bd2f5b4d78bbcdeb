// libFuzzer target: the values of the command line's structured flags, parsed as the
// CLI and the JSON options parse them: --map (one INPUT=CHANNEL per line), --sky,
// --composite and --terms. The input's first line selects nothing: every line is tried
// as each kind of value, so one corpus of flag values serves all four parsers.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "service/cli_options.h"
#include "service/pipeline.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<std::string> values(1);
  for (size_t i = 0; i < size; ++i) {
    if (data[i] == '\n') values.emplace_back();
    else values.back() += char(data[i]);
  }

  // All lines together as the --map list of one frame.
  ssdo::ReadOptionArgs args;
  args.maps = values;
  ssdo::ReadOptions read;
  std::string error;
  if (!ssdo::resolve_read_options(args, read, error) && error.empty()) std::abort();

  for (const std::string& v : values) {
    glm::vec3 top(-1), bottom(-1);
    error.clear();
    if (ssdo::parse_sky(v, top, bottom, error)) {
      // Accepted skies are non-negative finite radiance.
      for (int c = 0; c < 3; ++c)
        if (!(top[c] >= 0 && bottom[c] >= 0 && std::isfinite(top[c]) && std::isfinite(bottom[c]))) std::abort();
    } else if (error.empty()) {
      std::abort();
    }
    std::vector<ssdo::WeightedTerm> terms;
    error.clear();
    if (ssdo::parse_composite(v, terms, error)) {
      for (const ssdo::WeightedTerm& t : terms)
        if (!(t.weight >= 0.0f && t.weight <= 16.0f)) std::abort();
    } else if (error.empty()) {
      std::abort();
    }
    ssdo::TermSelection selection;
    error.clear();
    if (ssdo::parse_terms(v, selection, error)) {
      // What was accepted is spelled back and accepted again the same way.
      ssdo::TermSelection again;
      std::string error2;
      if (!ssdo::parse_terms(ssdo::to_string(selection), again, error2) ||
          ssdo::to_string(again) != ssdo::to_string(selection))
        std::abort();
    }
  }
  return 0;
}
