// Regression tests for inputs the fuzz target tests/fuzz/json_options_fuzz.cpp found.
// Each feeds the input itself.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "service/request_options.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

std::string write_temp(const std::string& name, const std::string& bytes) {
  const fs::path p = fs::temp_directory_path() / ("ssdo-options-regression-" + std::to_string(::getpid()) + "-" + name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p.string();
}

// A number too large for a double made nlohmann::json throw out_of_range (406), which
// load_json_file did not catch (only parse_error): `ssdo process --config FILE` ended in
// std::terminate. Fuzzer input json_options-crash-7f6e4b35 (shortened to its cause).
TEST(RequestOptionsRegression, NumberOverflowInAConfigIsAnError) {
  for (const std::string& text : {std::string(R"({"width": 8, "height": 1e309})"), std::string(R"({"fov": -1e400})"),
                                   std::string("{\"width\": 8, \"height\": 1e309oDepth.Z~5555,55\n")}) {
    const std::string path = write_temp("overflow.json", text);
    nlohmann::json j;
    std::string error;
    EXPECT_FALSE(load_json_file(path, j, error)) << text;
    EXPECT_NE(error.find("not valid JSON"), std::string::npos) << error;
    fs::remove(path);
  }
}

}  // namespace
}  // namespace ssdo
