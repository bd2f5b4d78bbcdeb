// What every start of the executable runs before its command (service/highway_timer.cpp).
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "run_binary.h"

namespace ssdo::test {
namespace {

// Highway's library, loaded by every ssdo process, calls TimerResolution from its static
// initializer: the dynamic linker must bind that call to the executable's definition (which
// skips the library's calibration of its benchmark timer), not to the library's own. (A
// Highway that calls nothing at start has nothing to bind: the test is skipped there.)
TEST(Startup, HighwayTimerCalibrationBindsToTheExecutable) {
  const ScopedVariable bindings("LD_DEBUG", "bindings");
  const RunResult r = run_ssdo("--version");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string symbol = "`_ZN3hwy8platform15TimerResolutionEv'";
  std::string binding;  // the dynamic linker's line for Highway's call of the symbol
  std::istringstream lines(r.output);
  for (std::string line; std::getline(lines, line);)
    if (line.find(symbol) != std::string::npos && line.find("libhwy") != std::string::npos) {
      binding = line;
      break;
    }
  if (binding.empty())  // a Highway that calibrates nothing at start
    GTEST_SKIP() << "Highway's library does not call TimerResolution when it is loaded";
  const size_t to = binding.find(" to ");
  ASSERT_NE(to, std::string::npos) << binding;
  ASSERT_LT(binding.find("libhwy"), to) << "the caller is Highway's library: " << binding;
  const std::string target = binding.substr(to + 4, binding.find(':', to) - (to + 4));
  EXPECT_EQ(target.find("libhwy"), std::string::npos) << "bound to the library's own calibration: " << binding;
  EXPECT_NE(target.find("ssdo"), std::string::npos) << binding;
}

}  // namespace
}  // namespace ssdo::test
