// Shared helpers of the formats tests: the shared data folder, scratch folders, small EXR
// files written with OpenImageIO (independent of the code under test), sidecar matrices.
#pragma once

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <glm/glm.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace ssdo::test {

namespace fs = std::filesystem;

inline fs::path shared_dir() { return fs::path(SSDO_SHARED_DIR); }
inline fs::path gbuffer_dir() { return shared_dir() / "gbuffers"; }
inline fs::path conformance_dir() { return shared_dir() / "exr-conformance"; }

#define SSDO_SKIP_WITHOUT(path)                                                   \
  do {                                                                            \
    if (!std::filesystem::exists(path))                                           \
      GTEST_SKIP() << "shared test data not found: " << (path).string()           \
                   << " (checkout without ../shared)";                            \
  } while (0)

struct ScratchDir {
  fs::path path;
  ScratchDir() {
    std::random_device rd;
    path = fs::temp_directory_path() /
           ("ssdo_formats_test_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  fs::path operator/(const std::string& name) const { return path / name; }
};

// One channel of a test image: name, sample type, values (row-major, width x height).
struct TestChannel {
  std::string name;
  OIIO::TypeDesc type = OIIO::TypeDesc::FLOAT;
  std::vector<float> values;
};

// Writes a scanline EXR with OpenImageIO. data_x/y: data window origin; display_*: display
// window (0 = same as the data window). Matrices are given in column-vector glm form and
// stored as M44f attributes (same 16 floats in memory order).
struct TestExr {
  int width = 0, height = 0;
  int data_x = 0, data_y = 0;
  int display_x = 0, display_y = 0, display_width = 0, display_height = 0;
  std::vector<TestChannel> channels;
  std::vector<std::pair<std::string, glm::mat4>> matrices;
  std::vector<std::pair<std::string, int>> int_attributes;
  std::vector<std::pair<std::string, float>> float_attributes;
  std::string compression = "zip";
  std::string part_name;  // in a multi-part file (write_parts)

  OIIO::ImageSpec spec() const {
    OIIO::ImageSpec spec(width, height, int(channels.size()), OIIO::TypeDesc::FLOAT);
    spec.x = data_x;
    spec.y = data_y;
    spec.full_x = display_width ? display_x : data_x;
    spec.full_y = display_height ? display_y : data_y;
    spec.full_width = display_width ? display_width : width;
    spec.full_height = display_height ? display_height : height;
    spec.channelnames.clear();
    spec.channelformats.clear();
    for (const auto& c : channels) {
      spec.channelnames.push_back(c.name);
      spec.channelformats.push_back(c.type);
    }
    spec.attribute("compression", compression);
    for (const auto& [name, m] : matrices)
      spec.attribute(name, OIIO::TypeDesc::TypeMatrix44, &m[0][0]);
    for (const auto& [name, v] : int_attributes) spec.attribute(name, v);
    for (const auto& [name, v] : float_attributes) spec.attribute(name, v);
    if (!part_name.empty()) spec.attribute("oiio:subimagename", part_name);
    return spec;
  }

  std::vector<float> interleaved() const {
    std::vector<float> pixels(size_t(width) * height * channels.size());
    for (size_t i = 0; i < size_t(width) * height; ++i)
      for (size_t c = 0; c < channels.size(); ++c) pixels[i * channels.size() + c] = channels[c].values[i];
    return pixels;
  }

  bool write(const fs::path& path, std::string* error = nullptr) const {
    auto out = OIIO::ImageOutput::create(path.string());
    if (!out || !out->open(path.string(), spec()) || !out->write_image(OIIO::TypeDesc::FLOAT, interleaved().data())) {
      if (error) *error = out ? out->geterror() : OIIO::geterror();
      return false;
    }
    return out->close();
  }
};

// A multi-part EXR of `parts`, in order (each named by its part_name).
inline bool write_parts(const fs::path& path, const std::vector<TestExr>& parts, std::string* error = nullptr) {
  std::vector<OIIO::ImageSpec> specs;
  for (const TestExr& p : parts) specs.push_back(p.spec());
  auto out = OIIO::ImageOutput::create(path.string());
  bool ok = out && out->open(path.string(), int(specs.size()), specs.data());
  for (size_t i = 0; ok && i < parts.size(); ++i)
    ok = (i == 0 || out->open(path.string(), specs[i], OIIO::ImageOutput::AppendSubimage)) &&
         out->write_image(OIIO::TypeDesc::FLOAT, parts[i].interleaved().data());
  if (!ok && error) *error = out ? out->geterror() : OIIO::geterror();
  return ok && out->close();
}

// Channels of one subimage, read as float with OpenImageIO (rows top to bottom).
inline std::vector<float> read_channels_oiio(const fs::path& path, const std::vector<std::string>& names,
                                             int subimage = 0, int* width = nullptr,
                                             int* height = nullptr) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) return {};
  if (subimage) in->seek_subimage(subimage, 0);
  const OIIO::ImageSpec spec = in->spec();
  std::vector<int> index;
  for (const auto& n : names) {
    const auto at = std::find(spec.channelnames.begin(), spec.channelnames.end(), n);
    if (at == spec.channelnames.end()) return {};
    index.push_back(int(at - spec.channelnames.begin()));
  }
  if (index.empty()) return {};
  // Only the span of channels asked for, as floats: a G-buffer of 40 channels read whole at
  // 1080p is 330 MB the test would fill and fault in.
  const int first = *std::min_element(index.begin(), index.end());
  const int span = *std::max_element(index.begin(), index.end()) + 1 - first;
  const size_t pixels = size_t(spec.width) * spec.height;
  std::vector<float> read(pixels * span);
  if (!in->read_image(subimage, 0, first, first + span, OIIO::TypeDesc::FLOAT, read.data())) return {};
  std::vector<float> out;
  out.reserve(pixels * names.size());
  for (size_t i = 0; i < pixels; ++i)
    for (int k : index) out.push_back(read[i * span + (k - first)]);
  if (width) *width = spec.width;
  if (height) *height = spec.height;
  return out;
}

// A row-major 4x4 JSON matrix as glm (column-major).
inline glm::mat4 json_matrix(const nlohmann::json& j) {
  glm::mat4 m(0.0f);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = j[r][c].get<float>();
  return m;
}

inline nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

}  // namespace ssdo::test
