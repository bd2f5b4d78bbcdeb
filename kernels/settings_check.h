// Validation helpers shared by the kernels' validate(settings) functions: one message
// format ("field = value is out of range R") and the radius checks every screen-space
// sampler repeats.
#pragma once

#include <cmath>
#include <string>

namespace ssdo::detail {

inline std::string out_of_range(const char* field, double value, const char* range) {
  return std::string(field) + " = " + std::to_string(value) + " is out of range " + range;
}

// radius_world in (0, inf) and max_radius_px in [2, 4096]; empty when both hold.
inline std::string check_radius(float radius_world, float max_radius_px) {
  if (!(radius_world > 0.0f) || !std::isfinite(radius_world))
    return out_of_range("radius_world", radius_world, "(0, inf)");
  if (!(max_radius_px >= 2.0f && max_radius_px <= 4096.0f))
    return out_of_range("max_radius_px", max_radius_px, "[2, 4096]");
  return {};
}

}  // namespace ssdo::detail
