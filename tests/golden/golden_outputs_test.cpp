// Output bytes of `ssdo process` on every shared frame: every term, each AO method at a
// half-resolution and a full-resolution preset, with 2 threads (and 1, but for the oracles).
//
// Two checks per case:
// - 1 and 2 threads write the same bits (DESIGN.md: same bytes out for 1 and N threads);
// - the bits equal tests/golden/outputs.csv, written by the build that made it. Changes to
//   the code's shape (not its arithmetic) must keep them; a change that alters numbers on
//   purpose regenerates the table (SSDO_UPDATE_GOLDEN=1 ctest -R Golden) and says so in its
//   commit. The table holds for one compiler and one instruction set (its first line);
//   another build compares threads only and says why it skips the table.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include "../integration/run_binary.h"

namespace ssdo::test {
namespace {

namespace fs = std::filesystem;

const fs::path kTable = source_dir() / "tests" / "golden" / "outputs.csv";

// FNV-1a over the bits of each sample as float (half samples widen exactly).
uint64_t fnv1a(const std::vector<float>& v, int channel, int nchannels) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = size_t(channel); i < v.size(); i += size_t(nchannels)) {
    uint32_t bits;
    std::memcpy(&bits, &v[i], 4);
    for (int b = 0; b < 4; ++b) {
      h ^= (bits >> (8 * b)) & 0xffu;
      h *= 1099511628211ull;
    }
  }
  return h;
}

// "channel" -> hash of every channel of an output EXR.
std::map<std::string, std::string> channel_hashes(const fs::path& exr) {
  std::map<std::string, std::string> out;
  auto in = OIIO::ImageInput::open(exr.string());
  if (!in) return out;
  const OIIO::ImageSpec& spec = in->spec();
  std::vector<float> values(size_t(spec.width) * spec.height * spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, values.data());
  for (int c = 0; c < spec.nchannels; ++c) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", (unsigned long long)fnv1a(values, c, spec.nchannels));
    out[spec.channelnames[c]] = hex;
  }
  return out;
}

struct Case {
  std::string name;
  std::vector<std::string> frames;
  std::string args;
  // Also run with 1 thread and compare with 2: the AO and SSDO kernels' own tests compare
  // thread counts on synthetic frames; here every fast case does on real ones.
  bool compare_threads = true;
};

std::vector<Case> cases() {
  const std::vector<std::string> all = {"cornell", "depthgap", "greeble", "perf1080", "orbit_f0", "orbit_f1",
                                        "orbit_f2", "orbit_f3", "orbit_f4", "orbit_f5", "orbit_f6"};
  const std::vector<std::string> small = {"cornell", "depthgap", "greeble"};
  std::vector<Case> c = {{"gtao_medium", all, "--method gtao --preset medium --ssdo-preset medium"}};
  for (const char* method : {"gtao", "hbao", "hemisphere"})
    for (const char* preset : {"low", "high"})
      if (std::string(method) + preset != "gtaomedium")
        c.push_back({std::string(method) + "_" + preset, small,
                     std::string("--method ") + method + " --preset " + preset + " --ssdo-preset " + preset});
  // The oracles (ray-marched AO and SSDO) take most of this test's time: one frame, 2
  // threads (their thread counts are compared in AoRaymarch.SameBytesForOneAndTwoThreads and
  // Ssdo.BitwiseIdenticalForOneAndTwoThreadsAndAnyRoi).
  c.push_back({"raymarch_low", {"cornell"}, "--method raymarch --preset low --ssdo-method oracle --ssdo-preset low",
               false});
  return c;
}

// "case frame channel" -> hash, from the table; its first line is the build key.
std::map<std::string, std::string> read_table(std::string& key) {
  std::map<std::string, std::string> t;
  std::ifstream f(kTable);
  std::getline(f, key);
  std::string line;
  while (std::getline(f, line)) {
    std::istringstream s(line);
    std::string c, frame, channel, hash;
    if (std::getline(s, c, ',') && std::getline(s, frame, ',') && std::getline(s, channel, ',') &&
        std::getline(s, hash))
      t[c + " " + frame + " " + channel] = hash;
  }
  return t;
}

TEST(Golden, EveryTermOfEverySharedFrameKeepsItsBits) {
  SSDO_REQUIRE_SHARED();
  const fs::path gb = shared_dir() / "gbuffers";
  const std::string build_key = SSDO_GOLDEN_BUILD_KEY;
  const bool update = std::getenv("SSDO_UPDATE_GOLDEN") != nullptr;
  std::string table_key;
  const std::map<std::string, std::string> table = read_table(table_key);
  const bool compare_table = !update && table_key == build_key;
  if (!update && !compare_table)
    std::printf("[ skip    ] the table was written by '%s', this build is '%s': threads compared only\n",
                table_key.c_str(), build_key.c_str());

  ScratchDir dir;
  std::ostringstream written;
  written << build_key << "\n";
  size_t compared = 0;
  for (const Case& c : cases()) {
    const fs::path in = dir.path / c.name;
    fs::create_directories(in);
    for (const std::string& f : c.frames) {
      fs::create_symlink(gb / (f + ".exr"), in / (f + ".exr"));
      fs::create_symlink(gb / (f + ".camera.json"), in / (f + ".camera.json"));
    }
    std::map<std::string, std::string> by_threads[2];
    for (int threads : {1, 2}) {
      if (threads == 1 && !c.compare_threads) continue;
      const fs::path out = dir.path / (c.name + "_t" + std::to_string(threads));
      const RunResult r = run_ssdo("process " + in.string() + " -o " + out.string() + " --terms all --env " +
                                   (gb / "env_equirect.exr").string() + " --jobs 1 --threads " +
                                   std::to_string(threads) + " " + c.args);
      ASSERT_EQ(r.exit_code, 0) << c.name << ":\n" << r.output;
      for (const std::string& f : c.frames) {
        const auto hashes = channel_hashes(out / (f + ".ssdo.exr"));
        ASSERT_GE(hashes.size(), 10u) << c.name << " " << f;
        for (const auto& [channel, hash] : hashes)
          by_threads[threads - 1][f + " " + channel] = hash;
      }
    }
    if (c.compare_threads) {
      EXPECT_EQ(by_threads[0], by_threads[1]) << c.name << ": 1 and 2 threads differ";
    }
    for (const auto& [frame_channel, hash] : by_threads[1]) {
      const std::string frame = frame_channel.substr(0, frame_channel.find(' '));
      const std::string channel = frame_channel.substr(frame_channel.find(' ') + 1);
      written << c.name << "," << frame << "," << channel << "," << hash << "\n";
      if (!compare_table) continue;
      const auto it = table.find(c.name + " " + frame_channel);
      ASSERT_NE(it, table.end()) << "not in the table: " << c.name << " " << frame_channel;
      EXPECT_EQ(it->second, hash) << c.name << " " << frame_channel << " changed";
      ++compared;
    }
  }
  if (update) {
    std::ofstream(kTable) << written.str();
    std::printf("[ update  ] %s written\n", kTable.c_str());
  } else if (compare_table) {
    EXPECT_EQ(compared, table.size()) << "the table has cases this run did not produce";
  }
}

}  // namespace
}  // namespace ssdo::test
