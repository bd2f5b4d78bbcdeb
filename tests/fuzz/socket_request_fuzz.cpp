// libFuzzer target: arbitrary bytes as everything one client sends on a connection to
// the real socket server of `ssdo serve` (service/socket_server.h): length prefixes,
// JSON headers, inline EXR payloads, paths inside and outside the allowed roots, frame
// options, several requests in a row.
//
// The server runs in this process with a frame service of no workers and a queue of
// capacity 0, so every request runs the whole of its validation (parsing, options, path
// policy, spooling of inline bytes) and a valid one is answered "busy" instead of being
// computed. Checks: the server neither crashes nor hangs, every answer is a well-formed
// length-prefixed JSON object with "ok", and the connection always ends.
#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "service/frame_service.h"
#include "service/protocol.h"
#include "service/socket_server.h"
#include "tests/fuzz/seed_exr.h"

namespace fs = std::filesystem;

namespace {

// Fixed, so seed inputs can name files under it: an allowed root with a frame, a
// camera file and a symlink that points out of the root.
constexpr const char* kRoot = "/tmp/ssdo-fuzz-socket/in";

std::string g_socket_path;
std::string g_private_dir;
std::unique_ptr<ssdo::FrameService> g_frames;
std::unique_ptr<ssdo::SocketServer> g_server;

void cleanup() {
  if (g_server) g_server->stop();
  g_server.reset();
  g_frames.reset();
  std::error_code ec;
  fs::remove_all(g_private_dir, ec);
}

bool read_exact(int fd, void* out, size_t size) {
  char* p = static_cast<char*>(out);
  while (size > 0) {
    const ssize_t n = ::read(fd, p, size);
    if (n == 0) return false;
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    size -= size_t(n);
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::error_code ec;
  fs::create_directories(fs::path(kRoot) / "sub", ec);
  const fs::path frame = fs::path(kRoot) / "frame.exr";
  if (!fs::exists(frame)) {
    const std::string temp = frame.string() + ".tmp" + std::to_string(::getpid());
    if (!ssdo::fuzz::write_seed_exr(temp, 0)) std::abort();
    fs::rename(temp, frame, ec);
  }
  fs::create_symlink("/etc/passwd", fs::path(kRoot) / "escape.exr", ec);
  fs::create_symlink("/etc", fs::path(kRoot) / "etc", ec);
  if (FILE* f = std::fopen((fs::path(kRoot) / "camera.json").c_str(), "wx")) {
    std::fputs("{\"width\": 8, \"height\": 6}\n", f);
    std::fclose(f);
  }

  g_private_dir = "/tmp/ssdo-fuzz-socket/p" + std::to_string(::getpid());
  fs::remove_all(g_private_dir, ec);
  fs::create_directories(fs::path(g_private_dir) / "out", ec);
  fs::create_directories(fs::path(g_private_dir) / "spool", ec);
  if (ec) std::abort();

  ssdo::FrameServiceOptions frame_options;
  frame_options.out_dir = g_private_dir + "/out";
  frame_options.workers = 0;
  frame_options.queue_capacity = 0;
  g_frames = std::make_unique<ssdo::FrameService>(frame_options);
  g_frames->start();

  ssdo::SocketServerOptions options;
  g_socket_path = g_private_dir + "/s";
  options.path = g_socket_path;
  options.allow_roots = {fs::canonical(kRoot).string()};
  options.out_dir = fs::canonical(g_private_dir + "/out").string();
  options.spool_dir = fs::canonical(g_private_dir + "/spool").string();
  options.limits.max_header_bytes = 1 << 16;
  options.limits.max_inline_bytes = 1 << 20;
  options.client_timeout_s = 5;
  options.max_clients = 4;
  g_server = std::make_unique<ssdo::SocketServer>(options, *g_frames);
  std::string error;
  if (!g_server->bind(error)) {
    std::fprintf(stderr, "socket fuzz target: %s\n", error.c_str());
    std::abort();
  }
  g_server->start();
  std::atexit(cleanup);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, g_socket_path.c_str(), g_socket_path.size() + 1);
  if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) std::abort();

  // Everything the client has to say, then the end of its stream. The server may close
  // early (a refused request): the rest is then not delivered, which is fine.
  for (size_t done = 0; done < size;) {
    const ssize_t n = ::send(fd, data + done, size - done, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    done += size_t(n);
  }
  ::shutdown(fd, SHUT_WR);

  // Every answer is a framed JSON object with "ok"; the server ends the connection.
  for (;;) {
    unsigned char prefix[4];
    if (!read_exact(fd, prefix, 4)) break;
    std::string body(ssdo::decode_length(prefix), '\0');
    if (body.size() > (size_t(1) << 20) || !read_exact(fd, body.data(), body.size())) std::abort();
    const nlohmann::json reply = nlohmann::json::parse(body, nullptr, false);
    if (!reply.is_object() || !reply.contains("ok") || !reply["ok"].is_boolean()) std::abort();
    if (reply.contains("inline_size")) std::abort();  // no frame is ever computed here
  }
  ::close(fd);
  return 0;
}
