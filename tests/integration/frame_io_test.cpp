// Frame I/O paths of `ssdo process`: the fast choices (compression, frames in parallel
// across workers) write the same numbers as the default path, and --io-only writes the
// same channels as a full run.
#include <cstring>
#include <filesystem>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include "run_binary.h"

namespace ssdo::test {
namespace {

namespace fs = std::filesystem;

struct Stored {
  std::vector<std::string> names;
  std::vector<OIIO::TypeDesc> types;
  std::string compression;
  std::vector<float> values;  // every channel, interleaved, as float (half widened exactly)
};

Stored read_all(const std::string& path) {
  Stored s;
  auto in = OIIO::ImageInput::open(path);
  if (!in) return s;
  const OIIO::ImageSpec& spec = in->spec();
  s.names = spec.channelnames;
  for (int c = 0; c < spec.nchannels; ++c) s.types.push_back(spec.channelformat(c));
  s.compression = spec.get_string_attribute("compression");
  s.values.resize(size_t(spec.width) * spec.height * spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, s.values.data());
  return s;
}

void copy_frame(const std::string& stem, const fs::path& dir, const std::string& as) {
  const fs::path frames = source_dir() / "examples" / "frames";
  fs::copy_file(frames / (stem + ".exr"), dir / (as + ".exr"));
  fs::copy_file(frames / (stem + ".camera.json"), dir / (as + ".camera.json"));
}

const std::string kTerms = " --terms ao,ssdo,composite --method gtao --preset low --ssdo-preset low";

TEST(FrameIo, FastPathsWriteTheSameNumbers) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_frame("cornell", dir.path / "in", "a");
  copy_frame("cornell", dir.path / "in", "b");
  // The reference: OpenEXR's default zip level through the whole path is not reachable from
  // the command line, so the reference is the sequential path with piz (lossless, another
  // codec); the fast paths: the default (zip level 1, one worker with every thread), no
  // compression, rle, and two single-threaded workers computing the frames side by side
  // (one reading or writing while the other computes).
  struct Path {
    const char* name;
    std::string args;
    const char* compression;
  };
  const std::vector<Path> paths = {{"piz", " --compression piz --jobs 1 --threads 1", "piz"},
                                   {"default", "", "zip"},
                                   {"none", " --compression none", "none"},
                                   {"rle", " --compression rle --jobs 1 --threads 2", "rle"},
                                   {"parallel", " --compression none --jobs 2 --threads 1", "none"}};
  std::vector<Stored> a, b;
  for (const Path& p : paths) {
    const fs::path out = dir.path / p.name;
    const RunResult r = run_ssdo("process " + (dir / "in") + " -o " + out.string() + kTerms + p.args);
    ASSERT_EQ(r.exit_code, 0) << p.name << ": " << r.output;
    a.push_back(read_all((out / "a.ssdo.exr").string()));
    b.push_back(read_all((out / "b.ssdo.exr").string()));
    ASSERT_FALSE(a.back().values.empty()) << p.name;
    EXPECT_EQ(a.back().compression, p.compression) << p.name;
  }
  ASSERT_EQ(a[0].names.size(), 21u);  // ao, ao_denoised, confidence, bent normal, 4 SSDO terms, composite
  // Every term in half float, AO and the confidence too (as Cycles stores its AO pass).
  for (size_t c = 0; c < a[0].types.size(); ++c) EXPECT_EQ(a[0].types[c], OIIO::TypeDesc::HALF) << a[0].names[c];
  for (size_t i = 0; i < paths.size(); ++i) {
    EXPECT_EQ(a[i].names, a[0].names) << paths[i].name;
    EXPECT_EQ(a[i].types, a[0].types) << paths[i].name;
    ASSERT_EQ(a[i].values.size(), a[0].values.size()) << paths[i].name;
    // Bit-identical: every codec stores the same half samples losslessly.
    EXPECT_EQ(std::memcmp(a[i].values.data(), a[0].values.data(), a[0].values.size() * sizeof(float)), 0)
        << paths[i].name;
    EXPECT_EQ(std::memcmp(b[i].values.data(), a[0].values.data(), a[0].values.size() * sizeof(float)), 0)
        << paths[i].name << " (second frame)";
  }
}

TEST(FrameIo, IoOnlyWritesTheSameChannelsAndComputesNothing) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  copy_frame("cornell", dir.path / "in", "a");
  for (const char* method : {"gtao", "hemisphere"}) {  // hemisphere has no bent normal
    const std::string terms = std::string(" --terms ao,ssdo,composite --preset low --ssdo-preset low --method ") + method;
    RunResult full = run_ssdo("process " + (dir / "in") + " -o " + (dir / "full") + terms + " --force");
    ASSERT_EQ(full.exit_code, 0) << full.output;
    RunResult io = run_ssdo("process " + (dir / "in") + " -o " + (dir / "io") + terms + " --io-only --force -v");
    ASSERT_EQ(io.exit_code, 0) << io.output;
    EXPECT_NE(io.output.find(" read "), std::string::npos) << io.output;  // the per-stage line
    const Stored f = read_all(dir / "full/a.ssdo.exr"), i = read_all(dir / "io/a.ssdo.exr");
    EXPECT_EQ(i.names, f.names) << method;
    EXPECT_EQ(i.types, f.types) << method;
    EXPECT_EQ(i.values.size(), f.values.size()) << method;
    EXPECT_NE(i.values, f.values) << method << ": stand-ins, not the computed terms";
  }
}

}  // namespace
}  // namespace ssdo::test
