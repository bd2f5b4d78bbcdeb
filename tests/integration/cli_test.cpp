// The real binary on real files: exit codes, messages, outputs.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_binary.h"

namespace ssdo::test {
namespace {

namespace fs = std::filesystem;

std::string example(const std::string& name) { return (source_dir() / "examples" / "frames" / name).string(); }

// The example cornell frame and its camera sidecar as FOLDER/STEM.exr and STEM.camera.json.
void copy_frame(const fs::path& folder, const std::string& stem) {
  fs::create_directories(folder);
  fs::copy_file(example("cornell.exr"), folder / (stem + ".exr"));
  fs::copy_file(example("cornell.camera.json"), folder / (stem + ".camera.json"));
}

// A numbered shot of `count` copies of it: FOLDER/shot.0001.exr ...
void copy_shot(const fs::path& folder, int count) {
  for (int f = 1; f <= count; ++f) {
    char stem[32];
    std::snprintf(stem, sizeof stem, "shot.%04d", f);
    copy_frame(folder, stem);
  }
}

std::vector<std::string> channel_names(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return {};
  return in->spec().channelnames;
}

TEST(Cli, HelpListsCommandsAndExamples) {
  const RunResult r = run_ssdo("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* word : {"info", "process", "eval", "Examples", "--fov"})
    EXPECT_NE(r.output.find(word), std::string::npos) << word;
}

TEST(Cli, NoCommandIsAnError) { EXPECT_NE(run_ssdo("").exit_code, 0); }

TEST(Cli, InfoNamesBlenderProfileAndSidecarCamera) {
  SSDO_REQUIRE_SHARED();
  const RunResult info = run_ssdo("info " + (shared_dir() / "gbuffers" / "cornell.exr").string());
  ASSERT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("blender"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("sidecar"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("640"), std::string::npos) << info.output;
}

TEST(Cli, InfoJsonIsParseable) {
  const RunResult r = run_ssdo("info --json " + example("cornell.exr") + " 2>/dev/null");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.output;
  EXPECT_NE(r.output.find("\"blender\""), std::string::npos);
}

// File names are bytes: one that is not UTF-8 comes out of --json with U+FFFD in place of
// the byte, and the command does not abort.
TEST(Cli, JsonOfANameThatIsNotUtf8IsParseable) {
  ScratchDir dir;
  copy_frame(dir.path, "\xff");
  for (const std::string command : {"info --json ", "eval --json --preset low --threads 1 "}) {
    const RunResult r = run_ssdo(command + "'" + dir / "\xff.exr" + "' 2>/dev/null");
    ASSERT_EQ(r.exit_code, 0) << command << r.output;
    const auto j = nlohmann::json::parse(r.output, nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << r.output;
    EXPECT_NE(r.output.find("\xef\xbf\xbd.exr"), std::string::npos) << r.output;
  }
}

// A frame with a back-face depth channel: `ssdo info` says where the back layer comes from,
// for a name the generic profile knows and for a mapped one.
TEST(Cli, InfoShowsTheBackLayer) {
  ScratchDir dir;
  const std::string path = (dir / "back.exr");
  OIIO::ImageSpec spec(4, 2, 3, OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"Z", "Z.back", "backface"};
  std::vector<float> pixels;
  for (int i = 0; i < 8; ++i) pixels.insert(pixels.end(), {2.0f, 2.5f, 3.0f});
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) && out->close());
  RunResult r = run_ssdo("info " + path + " --fov 60");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("back layer     channel Z.back"), std::string::npos) << r.output;
  r = run_ssdo("info --json " + path + " --fov 60 --map depth-back=backface 2>/dev/null");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.output;
  EXPECT_NE(r.output.find("\"back_layer\": \"channel backface\""), std::string::npos) << r.output;
  r = run_ssdo("info " + path + " --fov 60 --map depth-back=missing");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("mapped depth_back channel \"missing\" not found"), std::string::npos) << r.output;
}

// `ssdo info` of a radial depth gives its range as the file holds it and as the planar depth
// the terms use, each named; and a positions pass, found (P) or mapped, is said to be
// unused rather than left out silently. 3 x 1 pixels under a 90 degree field of view: the
// side pixels' eye rays are (+-2/3, 0, -1), so a radial 3 is a planar 3 / sqrt(13 / 9).
TEST(Cli, InfoSaysWhatARadialDepthHoldsAndThatPositionsAreUnused) {
  ScratchDir dir;
  const std::string path = (dir / "radial.exr");
  OIIO::ImageSpec spec(3, 1, 7, OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"P.X", "P.Y", "P.Z", "Z", "pos.X", "pos.Y", "pos.Z"};
  std::vector<float> pixels;
  for (int i = 0; i < 3; ++i) pixels.insert(pixels.end(), {1.0f, 2.0f, -3.0f, 3.0f, 1.0f, 2.0f, -3.0f});
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) && out->close());
  RunResult r = run_ssdo("info " + path + " --fov 90 --depth-kind radial");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("depth          radial (distance from the eye), converted to planar; foreground range 3 .. 3 "
                          "as stored (radial), 2.49615 .. 3 planar"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("position channels P.{X,Y,Z} are not used: view-space positions come from depth"),
            std::string::npos)
      << r.output;
  r = run_ssdo("info --json " + path + " --fov 90 --depth-kind radial --map position=pos 2>/dev/null");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.output;
  EXPECT_EQ(j[0]["depth_range_stored"], nlohmann::json({3.0, 3.0}));
  EXPECT_NEAR(j[0]["depth_range"][0].get<double>(), 3.0 / std::sqrt(13.0 / 9.0), 1e-5);
  bool noted = false;
  for (const auto& n : j[0]["notes"]) noted |= n.get<std::string>().find("position channels pos.{X,Y,Z} are not used") == 0;
  EXPECT_TRUE(noted) << r.output;
}

TEST(Cli, ProcessWritesTermsThenSkipsUpToDateFrames) {
  ScratchDir out;
  RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() +
                         " --terms ao --method gtao --preset low");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string written = out / "cornell.ssdo.exr";
  ASSERT_TRUE(fs::exists(written)) << r.output;
  const auto names = channel_names(written);
  EXPECT_NE(std::find(names.begin(), names.end(), "ao"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "ao_denoised"), names.end());
  EXPECT_NE(r.output.find("done 1, skipped 0, failed 0"), std::string::npos) << r.output;
  // No temporary file is left beside the output.
  for (const auto& e : fs::directory_iterator(out.path))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();

  r = run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() + " --terms ao --method gtao --preset low");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.output.find("done 0, skipped 1, failed 0"), std::string::npos) << r.output;
  r = run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() +
               " --terms ao --method gtao --preset low --force");
  EXPECT_NE(r.output.find("done 1, skipped 0, failed 0"), std::string::npos) << r.output;
}

// Frame "a" (cornell) in DIR/in processed into DIR/out with AO at low: the command, to run
// again.
std::string process_frame_a(const ScratchDir& dir) {
  copy_frame(dir.path / "in", "a");
  const std::string run = "process " + dir / "in" + " -o " + dir / "out" + " --terms ao --preset low";
  const RunResult r = run_ssdo(run);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return run;
}

// A rerun recomputes a frame whose camera sidecar changed after its output was written.
TEST(Cli, ARerunRecomputesAFrameWhoseSidecarChanged) {
  ScratchDir dir;
  const std::string run = process_frame_a(dir);
  RunResult r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
  fs::last_write_time(dir.path / "in" / "a.camera.json",
                      fs::last_write_time(dir.path / "out" / "a.ssdo.exr") + std::chrono::seconds(2));
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
}

// A rerun recomputes a frame whose output was made with other options (its header says
// which), or is not ssdo's; the thread count is not an option that changes an output.
TEST(Cli, ARerunWithOtherOptionsRecomputes) {
  ScratchDir dir;
  const std::string run = process_frame_a(dir);
  RunResult r = run_ssdo(run + " --threads 1");
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
  r = run_ssdo(run + " --radius 0.25");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 output was made with other options, other neighbouring frames or another ssdo version than "
                          "this run's: computed "
                          "again"),
            std::string::npos)
      << r.output;
  r = run_ssdo(run + " --radius 0.25");
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("other options"), std::string::npos) << r.output;
  // The same options in an output of another ssdo version (whose arithmetic may differ).
  const fs::path output = dir.path / "out" / "a.ssdo.exr";
  {
    OIIO::ImageBuf made(output.string());
    ASSERT_TRUE(made.read(0, 0, true)) << made.geterror();
    EXPECT_FALSE(made.spec().get_string_attribute("ssdo/version").empty());
    made.specmod().attribute("ssdo/version", "0.0.1");
    ASSERT_TRUE(made.write((dir.path / "older.exr").string())) << made.geterror();
  }
  fs::rename(dir.path / "older.exr", output);
  fs::last_write_time(output, fs::last_write_time(dir.path / "in" / "a.exr") + std::chrono::seconds(2));
  r = run_ssdo(run + " --radius 0.25");
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("another ssdo version"), std::string::npos) << r.output;
  // Another program's file by the output's name, newer than the frame.
  fs::remove(output);
  fs::copy_file(dir.path / "in" / "a.exr", output);
  fs::last_write_time(output, fs::last_write_time(dir.path / "in" / "a.exr") + std::chrono::seconds(2));
  r = run_ssdo(run + " --radius 0.25");
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 output was not readable as ssdo's (a damaged file, or another program's in its place)"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("other options"), std::string::npos) << r.output;
  const std::vector<std::string> names = channel_names(output.string());
  EXPECT_NE(std::find(names.begin(), names.end(), "ao"), names.end());
}

// A frame published as a symbolic link to one version of a render: pointing the link at
// another version, even an older file, makes a rerun compute the frame again.
TEST(Cli, ARerunFollowsAFrameLinkPointedAtAnotherFile) {
  ScratchDir dir;
  copy_frame(dir.path / "v1", "a");
  fs::create_directories(dir.path / "v2");
  fs::copy_file(example("greeble.exr"), dir.path / "v2" / "a.exr");
  fs::copy_file(example("greeble.camera.json"), dir.path / "v2" / "a.camera.json");
  const auto old = fs::last_write_time(dir.path / "v1" / "a.exr") - std::chrono::hours(1);
  for (const char* f : {"a.exr", "a.camera.json"}) fs::last_write_time(dir.path / "v2" / f, old);
  fs::create_directories(dir.path / "pub");
  auto publish = [&](const char* version) {
    for (const char* f : {"a.exr", "a.camera.json"}) {
      fs::remove(dir.path / "pub" / f);
      fs::create_symlink(fs::path("..") / version / f, dir.path / "pub" / f);
    }
  };
  publish("v1");
  const std::string run = "process " + dir / "pub/a.exr" + " -o " + dir / "out" + " --terms ao --preset low";
  RunResult r = run_ssdo(run);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
  publish("v2");
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
}

// AO alone never reads the environment light: the map's header is checked, its pixels are
// not decoded (a map whose pixels are damaged fails the frames that light with it only).
TEST(Cli, TheEnvironmentMapIsDecodedOnlyForTheTermsThatUseIt) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  const fs::path sky = dir.path / "sky.exr";
  fs::copy_file(source_dir() / "examples" / "env_equirect.exr", sky);
  fs::resize_file(sky, fs::file_size(sky) / 2);  // the header and the first chunks
  const std::string base = "process " + dir / "in" + " -o " + dir / "out" + " --preset low --force --env " + sky.string();
  RunResult r = run_ssdo(base + " --terms ao");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.path / "out" / "a.ssdo.exr"));
  r = run_ssdo(base + " --terms ao,composite");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(sky.string()), std::string::npos) << r.output;
}

// A folder where a frame's output goes fails that frame by name, and is not reported as an
// output made with other options first.
TEST(Cli, AFolderInPlaceOfAnOutputFailsThatFrameByName) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  fs::create_directories(dir.path / "out" / "a.ssdo.exr");
  fs::last_write_time(dir.path / "out" / "a.ssdo.exr", fs::file_time_type::clock::now() + std::chrono::hours(1));
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" + " --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(dir / "out/a.ssdo.exr" + ": is a folder"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("made with other options"), std::string::npos) << r.output;
}

// A composite that adds the frame's lighting, on a frame without a lighting pass, fails
// before any compute with a message that says what is missing and what to do.
TEST(Cli, ACompositeOfTheLightingNeedsALightingPass) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  OIIO::ImageBuf full(example("cornell.exr"));
  ASSERT_TRUE(full.read()) << full.geterror();
  const std::vector<std::string> names = {"ViewLayer.Depth.Z", "ViewLayer.Normal.X", "ViewLayer.Normal.Y",
                                          "ViewLayer.Normal.Z"};
  std::vector<int> order;
  for (const std::string& n : names) order.push_back(full.spec().channelindex(n));
  const OIIO::ImageBuf depth_normals = OIIO::ImageBufAlgo::channels(full, 4, order, {}, names);
  ASSERT_TRUE(depth_normals.write((dir.path / "in" / "bare.exr").string())) << depth_normals.geterror();
  fs::copy_file(example("cornell.camera.json"), dir.path / "in" / "bare.camera.json");
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" +
                               " --terms ao,composite --composite ambient_ao,lighting --preset low");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("the composite's term lighting adds the frame's own direct light, and the frame has no "
                          "lighting pass"),
            std::string::npos)
      << r.output;
}

// The environment's reach is said where a user may not expect it: the bounce of a frame
// with its own direct-light pass keeps that light; a directional environment under a camera
// from --fov (no world orientation) is turned with the view.
TEST(Cli, WhatTheEnvironmentDoesNotLightIsSaid) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  const std::string env = (source_dir() / "examples" / "env_equirect.exr").string();
  RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" + " --terms ssdo --preset low -v --env " + env);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("note: ssdo_indirect: its source light is the frame's own direct light"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("oriented as if the view were the world"), std::string::npos) << r.output;
  fs::remove(dir.path / "in" / "a.camera.json");
  r = run_ssdo("process " + dir / "in" + " -o " + dir / "out2" + " --terms ao,composite --preset low -v --fov 60 --env " + env);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("note: the environment is oriented as if the view were the world"), std::string::npos)
      << r.output;
  r = run_ssdo("process " + dir / "in" + " -o " + dir / "out3" + " --terms ao,composite --preset low -v --fov 60 --env-constant 2");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("oriented as if"), std::string::npos) << r.output;  // a constant has no direction
}

// The files the options name are part of what an output was made from: the header keeps
// the environment map's path as given (so a rerun with the same options skips, and the
// options work as a --config), and a changed map or --camera file makes the rerun compute.
TEST(Cli, ARerunFollowsTheEnvironmentMapAndCameraFileItWasGiven) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  fs::copy_file(source_dir() / "examples" / "env_equirect.exr", dir.path / "sky.exr");
  fs::rename(dir.path / "in" / "a.camera.json", dir.path / "cam.json");
  const std::string env = dir / "sky.exr", camera = dir / "cam.json";
  const std::string run = "process " + dir / "in" + " -o " + dir / "out" +
                          " --terms ao,ssdo --preset low --env " + env + " --camera " + camera;
  RunResult r = run_ssdo(run);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const fs::path output = dir.path / "out" / "a.ssdo.exr";
  auto in = OIIO::ImageInput::open(output.string());
  ASSERT_TRUE(in);
  const nlohmann::json options = nlohmann::json::parse(in->spec().get_string_attribute("ssdo/options"), nullptr, false);
  in.reset();
  EXPECT_EQ(options.value("env", ""), env);
  EXPECT_EQ(options.value("camera", ""), camera);
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
  // The recorded options as a config file give the same run.
  std::ofstream(dir.path / "made_with.json") << options.dump();
  r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" + " --config " + dir / "made_with.json");
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
  // Each file dated ahead of the output in turn; the output, once computed again, ahead of
  // that file (the next file goes further ahead).
  int ahead_s = 0;
  for (const std::string& changed : {env, camera}) {
    fs::last_write_time(changed, fs::file_time_type::clock::now() + std::chrono::seconds(ahead_s += 10));
    r = run_ssdo(run);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << changed << "\n" << r.output;
    fs::last_write_time(output, fs::file_time_type::clock::now() + std::chrono::seconds(ahead_s += 10));
  }
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
}

// An output cut short (an interrupted copy; a crash after the rename, before its data
// reached the disk) is no up-to-date output, whatever its header and date say.
TEST(Cli, AnOutputCutShortIsComputedAgain) {
  ScratchDir dir;
  const std::string run = process_frame_a(dir);
  const fs::path output = dir.path / "out" / "a.ssdo.exr";
  const auto whole_size = fs::file_size(output);
  fs::resize_file(output, whole_size - 1000);  // the header and most chunks are there
  RunResult r = run_ssdo(run);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("1 output was cut short"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("done 1, skipped 0"), std::string::npos) << r.output;
  EXPECT_EQ(fs::file_size(output), whole_size);
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 0, skipped 1"), std::string::npos) << r.output;
}

TEST(Cli, BadFrameFailsItsFrameNotTheBatch) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  std::ofstream(dir.path / "in" / "b.exr") << "not an exr";
  const RunResult r = run_ssdo("process " + (dir.path / "in").string() + " -o " + dir / "out" + " --terms ao");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("b.exr"), std::string::npos);
  EXPECT_NE(r.output.find("done 1, skipped 0, failed 1"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir.path / "out" / "a.ssdo.exr"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "b.ssdo.exr"));
}

TEST(Cli, UsageErrorsExitWithTwo) {
  ScratchDir out;
  EXPECT_EQ(run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() + " --terms fog").exit_code, 2);
  EXPECT_EQ(run_ssdo("process /nonexistent.exr -o " + out.path.string()).exit_code, 2);
  EXPECT_EQ(run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() + " --method magic").exit_code, 2);
  const RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() + " --chunk 0/4");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("count from 1"), std::string::npos) << r.output;
  // Values past what the field holds (a float's range; NaN seconds turned the timeout off)
  // ... and values no frame can be written with, refused before any frame is computed.
  for (const char* bad : {"--radius 1e39", "--env-constant 1e39", "--frame-timeout nan", "--frame-timeout 0",
                          "--composite ambient,ambient", "--compression dwaa --terms ao", "--env-constant 70000",
                          "--sky 70000,1"}) {
    const RunResult v = run_ssdo("process " + example("cornell.exr") + " -o " + out.path.string() + " " + bad);
    EXPECT_EQ(v.exit_code, 2) << bad << ": " << v.output;
  }
}

TEST(Cli, PatternsFramesAndChunksSelectFrames) {
  ScratchDir dir;
  copy_shot(dir.path, 6);
  const std::string pattern = dir / "shot.####.exr";
  RunResult r = run_ssdo("process '" + pattern + "' --frames 1-6x2 --chunk 2/2 -o " + dir / "out" +
                         " --terms ao --preset low");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // 1-6x2 = 1,3,5; chunk 2 of 2 = the slice [1, 3) of 3 frames = 3, 5.
  EXPECT_FALSE(fs::exists(dir.path / "out" / "shot.0001.ssdo.exr"));
  EXPECT_TRUE(fs::exists(dir.path / "out" / "shot.0003.ssdo.exr"));
  EXPECT_TRUE(fs::exists(dir.path / "out" / "shot.0005.ssdo.exr"));
  EXPECT_FALSE(fs::exists(dir.path / "out" / "shot.0002.ssdo.exr"));
  // A requested frame that does not exist is that frame's failure.
  r = run_ssdo("process '" + pattern + "' --frames 6-7 -o " + dir / "out" + " --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("shot.0007.exr"), std::string::npos) << r.output;
}

// Two inputs of one file name would write one output: refused before anything is
// computed. The same frame listed twice (overlapping ranges) is computed once. --frames
// without a pattern selects nothing: refused rather than ignored.
TEST(Cli, ABatchNeverWritesOneOutputTwice) {
  ScratchDir dir;
  for (const char* folder : {"a", "b"}) copy_frame(dir.path / folder, "shot.0001");
  const std::string quick = " --terms ao --preset low --views 0 --temporal 0";
  RunResult r = run_ssdo("process " + dir / "a/shot.0001.exr" + " " + dir / "b/shot.0001.exr" + " -o " +
                         dir / "out" + quick);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("would both write"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.path / "out" / "shot.0001.ssdo.exr"));

  r = run_ssdo("process '" + dir / "a/shot.####.exr" + "' --frames 1,1,1 -o " + dir / "out" + quick);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("done 1, skipped 0, failed 0"), std::string::npos) << r.output;

  r = run_ssdo("process " + dir / "b" + " --frames 1 -o " + dir / "out2" + quick);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--frames selects frames of a pattern"), std::string::npos) << r.output;
}

// A folder's frame that cannot be opened (a dangling link) is that frame's failure,
// wherever the folder lists it; the other frames are computed.
TEST(Cli, ADanglingLinkInAFolderFailsOnlyItsFrame) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "b");
  fs::create_symlink(dir.path / "nowhere", dir.path / "in" / "zz.exr");
  fs::create_symlink(dir.path / "nowhere", dir.path / "in" / "zz.txt");  // not a frame: ignored
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" + " --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("zz.exr"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("done 1, skipped 0, failed 1"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir.path / "out" / "b.ssdo.exr"));
}

// eval and bench report what they could not write, with a non-zero exit, and do not crash.
TEST(Cli, EvalAndBenchFailWhenTheyCannotWrite) {
  ScratchDir dir;
  std::ofstream(dir.path / "afile") << "x";
  RunResult r = run_ssdo("eval " + example("cornell.exr") + " --preset low --heatmap " + dir / "afile");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--heatmap"), std::string::npos) << r.output;
  fs::create_directories(dir.path / "maps" / "cornell.error.exr");  // a folder where the map goes
  r = run_ssdo("eval " + example("cornell.exr") + " --preset low --heatmap " + dir / "maps");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cornell.error.exr"), std::string::npos) << r.output;
  // Two files of one name would write one heatmap: refused before any work.
  fs::create_directories(dir.path / "other");
  fs::copy_file(example("cornell.exr"), dir.path / "other" / "cornell.exr");
  fs::copy_file(example("cornell.camera.json"), dir.path / "other" / "cornell.camera.json");
  r = run_ssdo("eval " + example("cornell.exr") + " " + dir / "other/cornell.exr" + " --preset low --heatmap " +
               dir / "maps2");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("would both write the heatmap " + dir / "maps2/cornell.error.exr"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir.path / "maps2" / "cornell.error.exr"));
  // A heatmap over one of the inputs ("other/cornell.exr" beside "other/cornell.error.exr"):
  // refused before any work, the input left as it was.
  fs::copy_file(example("cornell.exr"), dir.path / "other" / "cornell.error.exr");
  fs::copy_file(example("cornell.camera.json"), dir.path / "other" / "cornell.error.camera.json");
  const auto before = fs::last_write_time(dir.path / "other" / "cornell.error.exr");
  r = run_ssdo("eval " + dir / "other/cornell.exr" + " " + dir / "other/cornell.error.exr" +
               " --preset low --heatmap " + dir / "other");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("would be written over the input " + dir / "other/cornell.error.exr"), std::string::npos)
      << r.output;
  EXPECT_EQ(fs::last_write_time(dir.path / "other" / "cornell.error.exr"), before);
  EXPECT_EQ(fs::file_size(dir.path / "other" / "cornell.error.exr"), fs::file_size(example("cornell.exr")));
  // A folder where bench writes a table: refused before any frame is measured.
  fs::create_directories(dir.path / "bench" / "bench.csv");
  r = run_ssdo("bench " + example("cornell.exr") + " -o " + dir / "bench" +
               " --runs 1 --no-sweep --methods hemisphere --views 0 --temporal 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(dir / "bench/bench.csv" + " is a folder"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("hemisphere"), std::string::npos) << r.output;  // no row measured
  EXPECT_FALSE(fs::exists(dir.path / "bench" / "calibration.csv"));
}

// --threads beyond the cores runs on the cores: 1024 threads' stacks and OpenEXR's pool of
// 1024 exceeded the worker's default memory limit, and the frame failed as out of memory.
TEST(Cli, MoreThreadsThanCoresRunOnTheCores) {
  ScratchDir dir;
  const RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + dir / "out" +
                               " --terms ao --preset low --threads 1024");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.path / "out" / "cornell.ssdo.exr"));
}

// --quality auto says once what it chose (not again from each worker), and that it
// overrides an explicit --method.
TEST(Cli, QualityAutoSaysItsChoiceOnce) {
  ScratchDir dir;
  const RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + dir / "out" +
                               " --terms ao --quality auto --method hbao");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const size_t first = r.output.find("--quality auto --max-error");
  ASSERT_NE(first, std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("--quality auto --max-error", first + 1), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("give way to --quality auto"), std::string::npos) << r.output;
}

// The output of a crop sits where the crop does: its data and display windows are the
// input's (a compositor merges it over the plate in place).
TEST(Cli, ACropsOutputKeepsItsWindows) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  OIIO::ImageBuf full(example("cornell.exr"));
  OIIO::ImageBuf crop = OIIO::ImageBufAlgo::crop(full, OIIO::ROI(100, 300, 80, 230));
  ASSERT_TRUE(crop.write((dir.path / "in" / "crop.exr").string())) << crop.geterror();
  fs::copy_file(example("cornell.camera.json"), dir.path / "in" / "crop.camera.json");
  const RunResult r = run_ssdo("process " + dir / "in/crop.exr" + " -o " + dir / "out" + " --terms ao --preset low");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto in = OIIO::ImageInput::open((dir.path / "out" / "crop.ssdo.exr").string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.x, 100);
  EXPECT_EQ(spec.y, 80);
  EXPECT_EQ(spec.width, 200);
  EXPECT_EQ(spec.height, 150);
  EXPECT_EQ(spec.full_x, 0);
  EXPECT_EQ(spec.full_y, 0);
  EXPECT_EQ(spec.full_width, 640);
  EXPECT_EQ(spec.full_height, 360);
}

// A crop of a frame (data window inside the display window, at an even offset) gets the
// whole frame's noise, so its terms equal the whole frame's wherever its taps, the denoise
// and the upsample stay inside it: a re-rendered region patches into the frame without a
// seam of other noise.
TEST(Cli, ACropGetsTheWholeFramesTermsAwayFromItsEdges) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  OIIO::ImageBuf full(example("cornell.exr"));
  const OIIO::ROI region(102, 302, 82, 232);
  OIIO::ImageBuf crop = OIIO::ImageBufAlgo::crop(full, region);
  ASSERT_TRUE(crop.write((dir.path / "in" / "crop.exr").string())) << crop.geterror();
  fs::copy_file(example("cornell.exr"), dir.path / "in" / "full.exr");
  for (const char* stem : {"crop", "full"})
    fs::copy_file(example("cornell.camera.json"), dir.path / "in" / (std::string(stem) + ".camera.json"));
  // A radius of 10-20 pixels: the interior below is out of every tap's reach of the edges.
  const RunResult r = run_ssdo("process " + dir / "in" + " -o " + dir / "out" +
                               " --terms ao,ssdo --preset low --radius 0.2 --jobs 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  OIIO::ImageBuf crop_out((dir.path / "out" / "crop.ssdo.exr").string());
  OIIO::ImageBuf full_out((dir.path / "out" / "full.ssdo.exr").string());
  constexpr int kMargin = 40;
  const OIIO::ROI interior(region.xbegin + kMargin, region.xend - kMargin, region.ybegin + kMargin,
                           region.yend - kMargin);
  for (const char* name : {"ao", "ao_denoised", "ssdo_direct.R", "confidence"}) {
    const int cc = crop_out.spec().channelindex(name), cf = full_out.spec().channelindex(name);
    ASSERT_GE(cc, 0) << name;
    ASSERT_GE(cf, 0) << name;
    double sum = 0.0, worst = 0.0, value = 0.0;
    int n = 0;
    for (int y = interior.ybegin; y < interior.yend; ++y)
      for (int x = interior.xbegin; x < interior.xend; ++x) {
        const double d = std::abs(double(crop_out.getchannel(x, y, 0, cc)) - double(full_out.getchannel(x, y, 0, cf)));
        sum += d, worst = std::max(worst, d), ++n;
        value += full_out.getchannel(x, y, 0, cf);
      }
    std::printf("%s: value %.4f mean |difference| %.6f max %.6f over %d pixels\n", name, value / n, sum / n, worst, n);
    EXPECT_LT(sum / n, 1e-4) << name;
    if (std::string(name) == "ao") {
      EXPECT_LT(value / n, 0.99);  // occluded: the noise matters
    }
  }
}

// A sky brighter than half floats can hold, or near float's largest, gives finite outputs:
// the light terms saturate at 65504 where stored, never inf or NaN.
TEST(Cli, ASkyBrighterThanHalfGivesFiniteOutputs) {
  ScratchDir dir;
  for (const float radiance : {1e5f, 3e38f}) {
    const std::string env = dir / "env.exr";
    OIIO::ImageBuf sky(OIIO::ImageSpec(8, 4, 3, OIIO::TypeDesc::FLOAT));
    const float rgb[3] = {radiance, radiance, radiance};
    OIIO::ImageBufAlgo::fill(sky, rgb);
    ASSERT_TRUE(sky.write(env)) << sky.geterror();
    const RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + dir / "out" +
                                 " --terms all --preset low --force --env " + env);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    OIIO::ImageBuf out((dir.path / "out" / "cornell.ssdo.exr").string());
    ASSERT_TRUE(out.read()) << out.geterror();
    const OIIO::ImageBufAlgo::PixelStats stats = OIIO::ImageBufAlgo::computePixelStats(out);
    for (int c = 0; c < out.nchannels(); ++c) {
      EXPECT_EQ(stats.nancount[size_t(c)] + stats.infcount[size_t(c)], 0u) << radiance << " " << out.spec().channelnames[c];
      EXPECT_LE(stats.max[size_t(c)], 65504.0f) << out.spec().channelnames[c];
    }
    const int direct = out.spec().channelindex("ssdo_direct.R");
    ASSERT_GE(direct, 0);
    EXPECT_EQ(stats.max[size_t(direct)], 65504.0f) << radiance;  // saturated, not inf
  }
}

// A frame whose every depth sample is background (a negated depth pass): process warns
// without -v, and eval and bench refuse to report an error over no pixel.
TEST(Cli, AFrameWithoutForegroundIsWarnedAboutAndNotScored) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  OIIO::ImageBuf full(example("cornell.exr"));
  ASSERT_TRUE(full.read()) << full.geterror();
  const int depth = full.spec().channelindex("ViewLayer.Depth.Z");
  ASSERT_GE(depth, 0);
  std::vector<float> factors(size_t(full.nchannels()), 1.0f);
  factors[size_t(depth)] = -1.0f;
  const OIIO::ImageBuf negated = OIIO::ImageBufAlgo::mul(full, factors);
  ASSERT_TRUE(negated.write((dir.path / "in" / "neg.exr").string())) << negated.geterror();
  fs::copy_file(example("cornell.camera.json"), dir.path / "in" / "neg.camera.json");
  RunResult r = run_ssdo("process " + dir / "in/neg.exr" + " -o " + dir / "out" + " --terms ao --preset low");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("note: warning: no foreground pixel"), std::string::npos) << r.output;
  r = run_ssdo("eval " + dir / "in/neg.exr" + " --preset low");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("neg.exr: no pixel to compare: the frame has no foreground"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("MAE 0.0000"), std::string::npos) << r.output;
  // bench measures the frames that have a pixel to compare and leaves this one out of
  // every row (an MAE of 0 would be the chart's best point).
  fs::copy_file(example("cornell.exr"), dir.path / "in" / "ok.exr");
  fs::copy_file(example("cornell.camera.json"), dir.path / "in" / "ok.camera.json");
  r = run_ssdo("bench " + dir / "in/neg.exr" + " " + dir / "in/ok.exr" + " -o " + dir / "bench" +
               " --runs 1 --no-sweep --methods gtao --views 0 --temporal 0");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("neg.exr: no pixel to compare: the frame has no foreground"), std::string::npos) << r.output;
  const std::string csv = read_text(dir.path / "bench" / "bench.csv");
  EXPECT_EQ(csv.find("neg.exr"), std::string::npos) << csv;
  EXPECT_NE(csv.find("ok.exr"), std::string::npos) << csv;
  for (const std::string table : {"bench.csv", "calibration.csv"})
    EXPECT_EQ(read_text(dir.path / "bench" / table).find(",0,0"), std::string::npos) << table;
}

// The composite's ambient terms are lit by the environment, as SSDO is: four times the
// light, four times the foreground's composite (the background shows the light itself).
TEST(Cli, TheCompositesAmbientTermsFollowTheEnvironment) {
  ScratchDir dir;
  float foreground[2] = {};
  int n = 0;
  for (const char* radiance : {"1", "4"}) {
    const fs::path out = dir.path / radiance;
    const RunResult r = run_ssdo("process " + example("cornell.exr") + " -o " + out.string() +
                                 " --terms ao,composite --composite ambient_ao --preset low --env-constant " + radiance);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    OIIO::ImageBuf image((out / "cornell.ssdo.exr").string());
    const int c = image.spec().channelindex("composite.R");
    ASSERT_GE(c, 0);
    foreground[n++] = image.getchannel(320, 300, 0, c);
  }
  EXPECT_GT(foreground[0], 0.05f);
  EXPECT_NEAR(foreground[1], 4.0f * foreground[0], 0.002f * foreground[1]);
}

// A file named twice (however spelled) is evaluated once: the overall error is the file's.
TEST(Cli, EvalCountsAFileNamedTwiceOnce) {
  const std::string frame = example("cornell.exr");
  const std::string again = (fs::path(frame).parent_path() / ".." / "frames" / "cornell.exr").string();
  const RunResult r = run_ssdo("eval " + frame + " " + again + " --preset low --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.output;
  EXPECT_EQ(j["files"].size(), 1u) << r.output;
  EXPECT_EQ(j["overall"]["pixels"], j["files"][0]["pixels"]) << r.output;
}

// A black reference pass (mean 0) has no relative error: "n/a" and null, never 0%.
TEST(Cli, EvalOfABlackReferenceHasNoRelativeError) {
  ScratchDir dir;
  OIIO::ImageBuf full(example("cornell.exr"));
  ASSERT_TRUE(full.read()) << full.geterror();
  const int ao = full.spec().channelindex("ViewLayer.AO.R");
  ASSERT_GE(ao, 0);
  std::vector<float> factors(size_t(full.nchannels()), 1.0f);
  factors[size_t(ao)] = 0.0f;
  const OIIO::ImageBuf black = OIIO::ImageBufAlgo::mul(full, factors);
  ASSERT_TRUE(black.write(dir / "black.exr")) << black.geterror();
  fs::copy_file(example("cornell.camera.json"), dir.path / "black.camera.json");
  RunResult r = run_ssdo("eval " + dir / "black.exr" + " --preset low");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("(relative n/a: the reference's mean is not above 0)"), std::string::npos) << r.output;
  r = run_ssdo("eval " + dir / "black.exr" + " --preset low --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.output;
  EXPECT_TRUE(j["files"][0]["relative_mae"].is_null()) << r.output;
  EXPECT_TRUE(j["overall"]["relative_mae"].is_null()) << r.output;
  EXPECT_GT(j["overall"]["mae"].get<double>(), 0.1) << r.output;  // the estimate is not black
}

// An external cost that is no time or error (NaN, infinite, negative, "12ms") is refused by
// line before any frame is computed; a method given twice is measured once.
TEST(Cli, BenchRefusesExternalCostsThatAreNoNumbersAndRunsAMethodOnce) {
  ScratchDir dir;
  const std::string bench = "bench " + example("cornell.exr") + " --runs 1 --no-sweep --views 0 --temporal 0";
  for (const char* row : {"cycles,8 spp,nan,0.05", "cycles,8 spp,inf,0.05", "cycles,8 spp,-3,0.05",
                          "cycles,8 spp,3000,-0.1", "cycles,8 spp,12ms,0.05"}) {
    std::ofstream(dir.path / "ext.csv") << "series,label,ms,mae\ncycles,16 spp, 5900 ,0.03\n" << row << "\n";
    const RunResult r = run_ssdo(bench + " -o " + dir / "out" + " --methods gtao --external " + dir / "ext.csv");
    EXPECT_EQ(r.exit_code, 2) << row << "\n" << r.output;
    EXPECT_NE(r.output.find("ext.csv:3: "), std::string::npos) << row << "\n" << r.output;
    EXPECT_FALSE(fs::exists(dir.path / "out" / "bench.csv")) << row;
  }
  std::ofstream(dir.path / "ext.csv") << "series,label,ms,mae\ncycles,16 spp, 5900 ,0.03\n";
  const RunResult r = run_ssdo(bench + " -o " + dir / "out" + " --methods gtao gtao --external " +
                               dir / "ext.csv");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string csv = read_text(dir.path / "out" / "bench.csv");
  int rows = 0;
  for (size_t at = csv.find("\nall,gtao,low,"); at != std::string::npos; at = csv.find("\nall,gtao,low,", at + 1))
    ++rows;
  EXPECT_EQ(rows, 1) << csv;
}

// bench.csv is RFC 4180: a file name with a comma or a quote is one quoted field.
TEST(Cli, BenchQuotesAFileNameThatHoldsACommaOrAQuote) {
  ScratchDir dir;
  const fs::path frame = dir.path / "take 1, \"final\".exr";
  fs::copy_file(example("cornell.exr"), frame);
  fs::copy_file(example("cornell.camera.json"), dir.path / "take 1, \"final\".camera.json");
  const RunResult r = run_ssdo("bench '" + frame.string() + "' -o " + dir / "bench" +
                               " --runs 1 --no-sweep --methods gtao --views 0 --temporal 0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string csv = read_text(dir.path / "bench" / "bench.csv");
  const std::string field = "\"" + dir.path.string() + "/take 1, \"\"final\"\".exr\",gtao,";
  EXPECT_NE(csv.find("\n" + field), std::string::npos) << csv;
}

// A heatmap NAME.error.exr comes with its picture NAME.error.png (its "error" channel: the
// suffix once) and the estimate's and reference's NAME.error.<term>.png. A frame whose own
// name ends in ".error" keeps it: its maps differ from those of the frame named without it.
TEST(Cli, EvalHeatmapsSayErrorOnceAndNeverShareANameWithAnotherFrames) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  copy_frame(dir.path / "in", "a.error");
  const RunResult r = run_ssdo("eval " + dir / "in/a.exr" + " " + dir / "in/a.error.exr" + " --preset low --heatmap " +
                               dir / "heat");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir.path / "heat")) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"a.error.ao.png", "a.error.error.ao.png", "a.error.error.exr",
                                             "a.error.error.png", "a.error.error.reference.png", "a.error.exr",
                                             "a.error.png", "a.error.reference.png"}));
  // The picture of the heatmap is its "error" channel: 8-bit RGB, the frame's size, not the
  // estimate's picture.
  OIIO::ImageBuf heat((dir.path / "heat" / "a.error.png").string());
  OIIO::ImageBuf estimate((dir.path / "heat" / "a.error.ao.png").string());
  ASSERT_TRUE(heat.read()) << heat.geterror();
  ASSERT_TRUE(estimate.read()) << estimate.geterror();
  EXPECT_EQ(heat.spec().nchannels, 3);
  EXPECT_EQ(heat.spec().width, 640);
  EXPECT_EQ(heat.spec().height, 360);
  EXPECT_GT(OIIO::ImageBufAlgo::compare(heat, estimate, 0, 0).nfail, 0u);
}

// One file named twice under two spellings is not "two files of one name": its heatmap is
// written, while two files of one name in two folders are still refused.
TEST(Cli, EvalHeatmapOfOneFileNamedTwiceIsWritten) {
  ScratchDir dir;
  copy_frame(dir.path / "in", "a");
  copy_frame(dir.path / "other", "a");
  RunResult r = run_ssdo("eval " + dir / "in/a.exr" + " " + dir / "in/./a.exr" + " --preset low --heatmap " +
                         dir / "heat");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.path / "heat" / "a.error.exr"));
  r = run_ssdo("eval " + dir / "in/a.exr" + " " + dir / "other/a.exr" + " --preset low --heatmap " + dir / "heat2");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("would both write the heatmap"), std::string::npos) << r.output;
}

// A reference with NaN on part of the foreground: eval says how many pixels it left out,
// and its heatmap is black there, not NaN.
TEST(Cli, EvalLeavesOutAndSaysWhereTheReferenceIsNotFinite) {
  ScratchDir dir;
  fs::create_directories(dir.path / "in");
  OIIO::ImageBuf full(example("cornell.exr"));
  ASSERT_TRUE(full.read(0, 0, /*force=*/true, OIIO::TypeDesc::FLOAT)) << full.geterror();  // local pixels, writable
  const int ao = full.spec().channelindex("ViewLayer.AO.R");
  ASSERT_GE(ao, 0);
  std::vector<float> pixel(size_t(full.nchannels()));
  for (int y = 200; y < 240; ++y)
    for (int x = 300; x < 340; ++x) {
      full.getpixel(x, y, pixel.data());
      pixel[size_t(ao)] = std::numeric_limits<float>::quiet_NaN();
      full.setpixel(x, y, pixel.data());
    }
  ASSERT_TRUE(full.write((dir.path / "in" / "nan.exr").string())) << full.geterror();
  fs::copy_file(example("cornell.camera.json"), dir.path / "in" / "nan.camera.json");
  const RunResult r = run_ssdo("eval " + dir / "in/nan.exr" + " --preset low --heatmap " + dir / "heat");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("foreground pixels left out: the reference or the estimate is not finite there"),
            std::string::npos)
      << r.output;
  OIIO::ImageBuf heat((dir.path / "heat" / "nan.error.exr").string());
  ASSERT_TRUE(heat.read()) << heat.geterror();
  const OIIO::ImageBufAlgo::PixelStats stats = OIIO::ImageBufAlgo::computePixelStats(heat);
  for (const char* channel : {"error.R", "error.G", "error.B"}) {
    const int c = heat.spec().channelindex(channel);
    ASSERT_GE(c, 0) << channel;
    EXPECT_EQ(stats.nancount[size_t(c)], 0u) << channel;
  }
  const RunResult b = run_ssdo("bench " + dir / "in/nan.exr" + " -o " + dir / "bench" +
                               " --runs 1 --no-sweep --methods gtao --views 0 --temporal 0");
  EXPECT_EQ(b.exit_code, 0) << b.output;
  EXPECT_NE(b.output.find("nan.exr: 1600 foreground pixels left out"), std::string::npos) << b.output;
}

// A farm task given its range and the shot's (--frames 3 --shot-frames 1-6) takes its
// frames' neighbours from the whole shot, as a run of the whole shot does: frame 3's
// temporal neighbours are 1, 2, 4 and 5 although the task computes frame 3 alone.
TEST(Cli, AFarmTaskTakesItsNeighboursFromTheWholeShot) {
  ScratchDir dir;
  copy_shot(dir.path, 6);
  const RunResult r = run_ssdo("process '" + dir / "shot.####.exr" + "' --frames 3 --shot-frames 1-6 -o " +
                               dir / "out" + " --terms ao --preset low -v");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("temporal: shot.0002.exr shot.0004.exr shot.0001.exr shot.0005.exr"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir.path / "out" / "shot.0002.ssdo.exr"));  // neighbours are not written
}

// A frame of a shot not rendered (yet) does not make its neighbours' outputs stale: a rerun
// skips them and fails only that frame again; once it is rendered, the frames around it are
// computed again with it.
TEST(Cli, AMissingFrameOfAShotDoesNotMakeTheOthersStale) {
  ScratchDir dir;
  copy_shot(dir.path / "in", 4);
  fs::rename(dir.path / "in" / "shot.0003.exr", dir.path / "shot.0003.exr");
  const std::string run = "process '" + dir / "in/shot.####.exr" + "' --frames 1-4 -o " + dir / "out" +
                          " --terms ao --preset low --jobs 1";
  RunResult r = run_ssdo(run);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("done 3, skipped 0, failed 1"), std::string::npos) << r.output;
  r = run_ssdo(run);
  EXPECT_NE(r.output.find("done 0, skipped 3, failed 1"), std::string::npos) << r.output;
  fs::rename(dir.path / "shot.0003.exr", dir.path / "in" / "shot.0003.exr");
  fs::last_write_time(dir.path / "in" / "shot.0003.exr",
                      fs::last_write_time(dir.path / "out" / "shot.0004.ssdo.exr") + std::chrono::seconds(2));
  r = run_ssdo(run);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("done 4, skipped 0, failed 0"), std::string::npos) << r.output;
}

// A locked-off shot with one camera file (--camera, no sidecars): the neighbours are read
// with that camera as the frame is, so each frame is still filtered over them (they were
// read without it and skipped as frames without a camera).
TEST(Cli, OneCameraFileForAShotReachesTheNeighbours) {
  ScratchDir dir;
  copy_shot(dir.path / "in", 3);
  for (int f = 1; f <= 3; ++f) fs::remove(dir.path / "in" / ("shot.000" + std::to_string(f) + ".camera.json"));
  fs::copy_file(example("cornell.camera.json"), dir.path / "cam.json");
  const std::string shot = "'" + dir / "in/shot.####.exr" + "' --frames 1-3";
  RunResult r = run_ssdo("process " + shot + " -o " + dir / "out" + " --camera " + dir / "cam.json" +
                         " --terms ao --preset low --jobs 1 -v");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("temporal: shot.0001.exr shot.0003.exr"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("no camera"), std::string::npos) << r.output;
  r = run_ssdo("eval " + dir / "in/shot.0001.exr" + " " + dir / "in/shot.0002.exr" + " --camera " + dir / "cam.json" +
               " --preset low --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("no camera"), std::string::npos) << r.output;
}

// eval's reference follows the term: ssdo_direct against DiffDir unless told otherwise.
TEST(Cli, EvalComparesALightTermWithItsOwnPass) {
  const RunResult r = run_ssdo("eval " + example("greeble.exr") + " --term ssdo_direct --preset low --json --env " +
                               (source_dir() / "examples" / "env_equirect.exr").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(j.at("files").at(0).at("reference"), "DiffDir");
  EXPECT_LT(j.at("overall").at("mae").get<double>(), 0.2);
}

// eval --json lists the files that gave no measurement with their error (they were only on
// stderr, and a script reading the JSON saw fewer files and no failure).
TEST(Cli, EvalJsonListsTheFilesThatFailed) {
  ScratchDir dir;
  std::ofstream(dir / "broken.exr") << "not an image";
  const RunResult r =
      run_ssdo("eval " + example("greeble.exr") + " " + dir / "broken.exr" + " --preset low --json");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output.substr(r.output.find("{\n")), nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.output;
  EXPECT_EQ(j.at("files").size(), 1u);
  ASSERT_EQ(j.at("failed").size(), 1u) << r.output;
  EXPECT_EQ(j.at("failed").at(0).at("path"), dir / "broken.exr");
  EXPECT_NE(j.at("failed").at(0).at("error").get<std::string>().find("broken.exr"), std::string::npos);
}

// The preset eval reports is the one it computed with: SSDO's --ssdo-preset, --quality
// auto's choice for AO (never the --preset default they replaced).
TEST(Cli, EvalReportsThePresetItComputedWith) {
  const std::string env = (source_dir() / "examples" / "env_equirect.exr").string();
  RunResult r = run_ssdo("eval " + example("greeble.exr") + " --term ssdo_direct --ssdo-preset low --json --env " + env);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  nlohmann::json j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(j.at("files").at(0).at("preset"), "low") << r.output;
  r = run_ssdo("eval " + example("greeble.exr") + " --quality auto --max-error 0 --preset low --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const size_t chosen = r.output.find("--quality auto --max-error 0: ");
  ASSERT_NE(chosen, std::string::npos) << r.output;
  std::istringstream words(r.output.substr(chosen + std::string("--quality auto --max-error 0: ").size()));
  std::string method, preset;
  words >> method >> preset;
  j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(j.at("files").at(0).at("method"), method) << r.output;
  EXPECT_EQ(j.at("files").at(0).at("preset"), preset) << r.output;
  EXPECT_NE(preset, "low");
}

}  // namespace
}  // namespace ssdo::test
