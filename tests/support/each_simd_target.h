// Runs a test body once per instruction set this CPU runs (among those the dispatcher may
// choose after SSDO_SIMD's choice: the best down to the baseline), so that one test run
// checks every dispatched path the CPU has, not only the best one. The choice made before
// is restored afterwards.
#pragma once

#include <hwy/targets.h>

#include <string>

namespace ssdo::test {

// Highway's dispatch tables call the target its ChosenTarget holds; SupportedTargets()
// resets that choice, so it is set again from its result (as core/simd.cpp does).
inline void choose_supported_simd_targets() {
  hwy::GetChosenTarget().Update(hwy::SupportedTargets());
}

// body(name) per target, the best first. Highway never disables the baseline, so each
// run has its target and the baseline, and picks its target.
template <class Body>
void for_each_simd_target(Body&& body) {
  const int64_t before = hwy::SupportedTargets();
  for (int64_t rest = before; rest != 0; rest &= rest - 1) {
    const int64_t target = rest & -rest;
    hwy::DisableTargets(~target);
    choose_supported_simd_targets();
    body(std::string(hwy::TargetName(target)));
  }
  hwy::DisableTargets(~before);
  choose_supported_simd_targets();
}

}  // namespace ssdo::test
