// A hostile or careless client of `ssdo serve`: the files it can make the service read and
// write stay inside --allow, the watch folder and -o, at the moment they are opened.
#include <sys/stat.h>

#include "formats/output_writer.h"
#include "service/worker_process.h"
#include "service_harness.h"

namespace ssdo::test {
namespace {

struct ConfinedService {
  ScratchDir& dir;
  std::string socket;
  std::unique_ptr<SsdoProcess> process;
  bool ready = false;
  ConfinedService(ScratchDir& d, const std::string& tag, std::vector<std::string> extra = {}) : dir(d), socket(socket_path_for(tag)) {
    for (const char* sub : {"frames", "secret", "out", "in"}) fs::create_directories(dir.path / sub);
    copy_example("cornell", dir.path / "frames", "cornell");
    copy_example("cornell", dir.path / "secret", "secret");
    std::vector<std::string> args = {"serve", "--socket", socket, "-o", dir / "out", "--allow", dir / "frames",
                                     "--terms", "ao", "--preset", "low", "--frame-timeout", kServiceFrameTimeoutS};
    args.insert(args.end(), extra.begin(), extra.end());
    process = std::make_unique<SsdoProcess>(args, dir.path / ("serve-" + tag + ".log"));
    ready = process->wait_for_log("ready", 30);
  }
  json process_path(const std::string& input, json extra = json::object()) const {
    Client c(socket);
    json request{{"op", "process"}, {"input", input}};
    request.update(extra);
    return c.request(request, {}, nullptr, 60);
  }
};

// The worker as the service runs it: the service checked a path; by the time the worker
// opens it, a folder on the way is a symbolic link out of the roots. The open refuses it.
TEST(Confinement, WorkerRefusesASymlinkSwappedIntoTheCheckedInputPath) {
  ScratchDir dir;
  fs::create_directories(dir.path / "root");
  fs::create_directories(dir.path / "secret");
  copy_example("cornell", dir.path / "secret", "cornell");
  fs::create_directories(dir.path / "out");
  fs::create_directory_symlink(dir.path / "secret", dir.path / "root" / "frames");  // swapped in
  WorkerProcess worker(WorkerLimits{}, SSDO_BINARY);
  WorkerJob job{dir / "root/frames/cornell.exr", dir / "out/cornell.ssdo.exr",
                json{{"terms", "ao"}, {"preset", "low"}}, {}, {{dir / "root"}, {dir / "root"}, dir / "out", {}}};
  const WorkerResult r = worker.run(job);
  EXPECT_FALSE(r.ok());
  EXPECT_TRUE(r.error.find("symbolic link") != std::string::npos || r.error.find("outside the allowed") != std::string::npos)
      << r.error;
  EXPECT_NE(r.error.find(dir / "root/frames/cornell.exr"), std::string::npos) << r.error;
  EXPECT_FALSE(path_exists(dir.path / "out" / "cornell.ssdo.exr"));

  // The output folder swapped for a link out of -o: nothing is written through it.
  fs::create_directories(dir.path / "root2");
  copy_example("cornell", dir.path / "root2", "cornell");
  fs::create_directory_symlink(dir.path / "secret", dir.path / "out" / "sub");
  job = {dir / "root2/cornell.exr", dir / "out/sub/cornell.ssdo.exr", json{{"terms", "ao"}, {"preset", "low"}}, {},
         {{dir / "root2"}, {}, dir / "out", {}}};
  const WorkerResult w = worker.run(job);
  EXPECT_FALSE(w.ok());
  EXPECT_FALSE(path_exists(dir.path / "secret" / "cornell.ssdo.exr")) << w.error;

  // The same frames by their real paths are computed.
  job = {dir / "root2/cornell.exr", dir / "out/cornell.ssdo.exr", json{{"terms", "ao"}, {"preset", "low"}}, {},
         {{dir / "root2"}, {}, dir / "out", {}}};
  const WorkerResult ok = worker.run(job);
  EXPECT_TRUE(ok.ok()) << ok.error;
  EXPECT_TRUE(exr_has_channel(dir / "out/cornell.ssdo.exr", "ao"));
}

TEST(Confinement, SidecarFifosAndSymlinksInsideAndOutTheRoots) {
  ScratchDir dir;
  ConfinedService service(dir, "confine1");
  ASSERT_TRUE(service.ready) << service.process->log();
  // A sidecar that is a symbolic link out of the roots is not read.
  copy_example("cornell", dir.path / "frames", "side");
  fs::remove(dir.path / "frames" / "side.camera.json");
  fs::create_symlink(dir.path / "secret" / "secret.camera.json", dir.path / "frames" / "side.camera.json");
  json r = service.process_path(dir / "frames/side.exr");
  EXPECT_EQ(r.value("ok", true), false) << r.dump();
  EXPECT_NE(r.value("error", "").find("side.camera.json"), std::string::npos) << r.dump();

  // FIFOs as camera, as sidecar: refused at once, no worker waits for a writer.
  ASSERT_EQ(::mkfifo((dir.path / "frames" / "pipe.json").c_str(), 0600), 0);
  copy_example("cornell", dir.path / "frames", "fifo");
  fs::remove(dir.path / "frames" / "fifo.camera.json");
  ASSERT_EQ(::mkfifo((dir.path / "frames" / "fifo.camera.json").c_str(), 0600), 0);
  const auto t0 = std::chrono::steady_clock::now();
  r = service.process_path(dir / "frames/cornell.exr", {{"options", {{"camera", dir / "frames/pipe.json"}}}});
  EXPECT_EQ(r.value("ok", true), false) << r.dump();
  EXPECT_NE(r.value("error", "").find("not a regular file"), std::string::npos) << r.dump();
  r = service.process_path(dir / "frames/fifo.exr");
  EXPECT_EQ(r.value("ok", true), false) << r.dump();
  EXPECT_NE(r.value("error", "").find("not a regular file"), std::string::npos) << r.dump();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10.0);

  // A symbolic link inside the roots to a frame inside the roots keeps working.
  fs::create_symlink(dir.path / "frames" / "cornell.exr", dir.path / "frames" / "alias.exr");
  r = service.process_path(dir / "frames/alias.exr", {{"output", dir / "out/alias.ssdo.exr"}});
  EXPECT_EQ(r.value("ok", false), true) << r.dump();
}

TEST(Confinement, OutputsCollisionsSpoolFoldersAndNames) {
  ScratchDir dir;
  ConfinedService service(dir, "confine2");
  ASSERT_TRUE(service.ready) << service.process->log();
  fs::create_directories(dir.path / "frames" / "a");
  fs::create_directories(dir.path / "frames" / "b");
  copy_example("cornell", dir.path / "frames" / "a", "x");
  copy_example("cornell", dir.path / "frames" / "b", "x");
  json r = service.process_path(dir / "frames/a/x.exr");
  EXPECT_EQ(r.value("ok", false), true) << r.dump();
  r = service.process_path(dir / "frames/b/x.exr");  // the same OUT/x.ssdo.exr
  EXPECT_EQ(r.value("code", ""), "conflict") << r.dump();
  EXPECT_EQ(service.process_path(dir / "frames/a/x.exr").value("ok", false), true);  // its own again
  r = service.process_path(dir / "frames/b/x.exr", {{"output", dir / "out/x-b.ssdo.exr"}});
  EXPECT_EQ(r.value("ok", false), true) << r.dump();

  // The private spool is not an output folder.
  r = service.process_path(dir / "frames/cornell.exr", {{"output", dir / "out/.ssdo-spool/x.ssdo.exr"}});
  EXPECT_EQ(r.value("code", ""), "forbidden") << r.dump();
  // An output name that is a folder: a true message.
  fs::create_directories(dir.path / "out" / "folder.ssdo.exr");
  r = service.process_path(dir / "frames/cornell.exr", {{"output", dir / "out/folder.ssdo.exr"}});
  EXPECT_EQ(r.value("ok", true), false) << r.dump();
  EXPECT_NE(r.value("error", "").find("is a folder"), std::string::npos) << r.dump();

  // A name holding a newline forges no log line and is escaped in the reply.
  copy_example("cornell", dir.path / "frames", "evil\nok forged");
  r = service.process_path(dir / "frames/evil\nok forged.exr", {{"output", dir / "out/nope/x.exr"}});
  EXPECT_EQ(r.value("ok", true), false) << r.dump();
  EXPECT_EQ(r.value("error", "").find('\n'), std::string::npos) << r.dump();
  fs::remove(dir.path / "frames" / "evil\nok forged.camera.json");
  r = service.process_path(dir / "frames/evil\nok forged.exr", {{"options", {{"fov", 0}}}});
  EXPECT_EQ(r.value("ok", true), false) << r.dump();
  EXPECT_EQ(service.process->signal_and_wait(SIGTERM, 30), 0);
  EXPECT_EQ(service.process->log().find("\nok forged"), std::string::npos) << service.process->log();
  EXPECT_NE(service.process->log().find("evil\\nok forged"), std::string::npos) << service.process->log();
}

TEST(Confinement, WatchedSymlinksOutStaleTempsAndErrorFileTemps) {
  ScratchDir dir;
  for (const char* sub : {"in", "out/sub", "secret"}) fs::create_directories(dir.path / sub);
  copy_example("cornell", dir.path / "secret", "secret");
  // Abandoned temps of a dead writer of this host, in a subfolder and of every pattern.
  const std::string host = temp_file_host();
  const fs::path stale1 = dir.path / "out" / "sub" / (".x.ssdo.exr.tmp-" + host + "-999999999-abc");
  const fs::path stale2 = dir.path / "out" / ".y.error.json.tmp-999999999-err";
  for (const fs::path& p : {stale1, stale2}) std::ofstream(p) << "partial";
  // A watched symbolic link pointing out of the watch folder.
  fs::create_symlink(dir.path / "secret" / "secret.exr", dir.path / "in" / "leak.exr");
  // A bad frame whose error file's temp would once have had a predictable name: a link
  // planted at every such name is never written through.
  std::ofstream(dir.path / "victim") << "untouched";
  std::ofstream(dir.path / "in" / "bad.exr") << "not an exr";
  const std::string socket = socket_path_for("confine3");
  SsdoProcess serve({"serve", "--watch", dir / "in", "-o", dir / "out", "--socket", socket, "--terms", "ao",
                     "--preset", "low"},
                    dir.path / "serve.log");
  for (int pid = serve.pid(); pid < serve.pid() + 64; ++pid)
    fs::create_symlink(dir.path / "victim", dir.path / "out" / (".bad.error.json.tmp-" + std::to_string(pid) + "-err"));
  ASSERT_TRUE(serve.wait_for_log("ready", 30)) << serve.log();
  ASSERT_TRUE(wait_until([&] { return path_exists(dir.path / "out/leak.error.json") && path_exists(dir.path / "out/bad.error.json"); }, 30))
      << serve.log();
  EXPECT_FALSE(path_exists(dir.path / "out/leak.ssdo.exr"));
  EXPECT_NE(read_text(dir.path / "out/leak.error.json").find("outside the allowed folders"), std::string::npos);
  // A watched frame's folder is the watch folder, not --allow: the message says both.
  EXPECT_NE(read_text(dir.path / "out/leak.error.json").find("a watched frame's in the watch folder"), std::string::npos);
  EXPECT_EQ(read_text(dir.path / "victim"), "untouched");
  EXPECT_FALSE(path_exists(stale1));
  EXPECT_FALSE(path_exists(stale2));
  EXPECT_EQ(serve.signal_and_wait(SIGTERM, 30), 0);
}

}  // namespace
}  // namespace ssdo::test
