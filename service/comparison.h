// What `eval` and `bench` say about a frame's comparison with its reference pass before
// they report its error.
#pragma once

#include <cstdint>
#include <string>

#include "formats/gbuffer_reader.h"

namespace ssdo {

// Why the comparison of a frame says nothing: no pixel was compared (an MAE of 0 would
// read as perfect). `compared`: pixels compared; `foreground`: the frame's foreground
// pixels. Empty when some pixel was compared.
inline std::string no_comparison_reason(int64_t compared, int64_t foreground) {
  if (compared > 0) return {};
  return "no pixel to compare: " + (foreground == 0
                                        ? "the frame has no foreground: " + std::string(kNoForeground)
                                        : std::string("the reference is not finite on any foreground pixel"));
}

// The note for foreground pixels the comparison left out; empty when none were.
inline std::string left_out_note(int64_t compared, int64_t foreground) {
  if (compared >= foreground) return {};
  return std::to_string(foreground - compared) +
         " foreground pixels left out: the reference or the estimate is not finite there";
}

}  // namespace ssdo
