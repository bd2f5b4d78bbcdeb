#include "core/simd.h"

#include <hwy/highway.h>
#include <hwy/targets.h>

#include <algorithm>
#include <cctype>
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

// The targets disabled now (Highway has no getter for them).
int64_t g_disabled = 0;

void disable_targets(int64_t disabled) {
  g_disabled = disabled;
  hwy::DisableTargets(disabled);
  choose_supported_targets();
}

// Every compiled target this CPU runs, whatever is disabled now.
int64_t runnable_targets() {
  hwy::DisableTargets(0);
  const int64_t targets = hwy::SupportedTargets() & HWY_TARGETS;
  disable_targets(g_disabled);
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

void use_baseline_simd() { disable_targets(~int64_t(HWY_STATIC_TARGET)); }

void use_best_simd() { disable_targets(0); }

std::string simd_baseline_target() { return hwy::TargetName(HWY_STATIC_TARGET); }

std::vector<std::string> simd_targets_runnable() {
  std::vector<std::string> names;
  for (int64_t targets = runnable_targets(); targets != 0; targets &= targets - 1)
    names.push_back(hwy::TargetName(targets & -targets));
  return names;
}

bool use_simd_target(std::string_view name) {
  for (int64_t targets = runnable_targets(); targets != 0; targets &= targets - 1) {
    const int64_t bit = targets & -targets;
    const std::string_view target = hwy::TargetName(bit);
    const bool same =
        target.size() == name.size() && std::equal(target.begin(), target.end(), name.begin(), [](char a, char b) {
          return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
        });
    if (!same) continue;
    disable_targets(bit - 1);  // the better targets are the lower bits
    return true;
  }
  return false;
}

bool apply_simd_choice(const char* value, std::string& error) {
  if (value == nullptr || *value == '\0') return true;
  if (std::strcmp(value, "best") == 0) {
    use_best_simd();
    return true;
  }
  if (std::strcmp(value, "baseline") == 0) {
    use_baseline_simd();
    return true;
  }
  if (use_simd_target(value)) return true;
  std::string names;
  for (const std::string& n : simd_targets_runnable()) names += (names.empty() ? "" : ", ") + n;
  error = std::string("SSDO_SIMD='") + value +
          "': expected best, baseline or an instruction set this build and CPU run (" + names + ")";
  return false;
}

}  // namespace ssdo
