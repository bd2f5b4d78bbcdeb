#include "core/simd.h"

#include <hwy/highway.h>
#include <hwy/targets.h>

#include <cstring>

namespace ssdo {
namespace {

// Highway's dispatch tables call the target its ChosenTarget holds. SupportedTargets()
// itself resets that choice to every target the CPU runs before applying the disabled
// ones, so the choice is set again from its result after every call to it.
int64_t choose_supported_targets() {
  const int64_t targets = hwy::SupportedTargets();
  hwy::GetChosenTarget().Update(targets);
  return targets;
}

}  // namespace

std::string simd_target() {
  const int64_t usable = choose_supported_targets() & HWY_TARGETS;
  return hwy::TargetName(usable & -usable);  // the lowest bit is the best target
}

std::string simd_targets_compiled() {
  std::string names;
  for (int64_t targets = HWY_TARGETS; targets != 0; targets &= targets - 1) {
    if (!names.empty()) names += ",";
    names += hwy::TargetName(targets & -targets);
  }
  return names;
}

void use_baseline_simd() {
  hwy::DisableTargets(~int64_t(HWY_STATIC_TARGET));
  choose_supported_targets();
}

void use_best_simd() {
  hwy::DisableTargets(0);
  choose_supported_targets();
}

std::string simd_baseline_target() { return hwy::TargetName(HWY_STATIC_TARGET); }

bool apply_simd_choice(const char* value, std::string& error) {
  if (value == nullptr || *value == '\0' || std::strcmp(value, "best") == 0) return true;
  if (std::strcmp(value, "baseline") == 0) {
    use_baseline_simd();
    return true;
  }
  error = std::string("SSDO_SIMD='") + value + "': expected best or baseline";
  return false;
}

}  // namespace ssdo
