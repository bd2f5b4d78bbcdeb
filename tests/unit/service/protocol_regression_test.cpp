// Regression tests for inputs the fuzz targets of tests/fuzz/ (or their review) found to
// crash or mis-handle the socket request path. Each feeds the input itself.
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "service/frame_service.h"
#include "service/protocol.h"
#include "service/socket_server.h"

namespace ssdo {
namespace {

namespace fs = std::filesystem;

std::string nested(const std::string& open, const std::string& close, int depth) {
  std::string s;
  s.reserve(size_t(depth) * (open.size() + close.size()));
  for (int i = 0; i < depth; ++i) s += open;
  for (int i = 0; i < depth; ++i) s += close;
  return s;
}

// A 1 MiB header may nest arrays 500,000 deep. Copying such an "id" (or "sidecar",
// "options") into the request, or dumping it into the reply, recursed once per level and
// overflowed the stack: one request ended the whole service (SIGSEGV).
TEST(ProtocolRegression, DeeplyNestedFieldsAreRefusedWithoutRecursion) {
  for (const char* field : {"id", "options", "sidecar", "unknown"}) {
    const std::string header = std::string(R"({"op": "process", "inline_size": 10, ")") + field +
                               "\": " + nested("[", "]", 200000) + "}";
    SocketRequest request;
    std::string error;
    EXPECT_FALSE(parse_socket_request(header, ProtocolLimits{}, request, error)) << field;
    EXPECT_NE(error.find("nests deeper"), std::string::npos) << error;
  }
  const std::string objects = R"({"op": "ping", "id": )" + nested(R"({"a": )", "}", 200000) + "}";
  SocketRequest request;
  std::string error;
  EXPECT_FALSE(parse_socket_request(objects, ProtocolLimits{}, request, error));
}

TEST(ProtocolRegression, NestingUpToTheLimitIsAccepted) {
  const std::string header = R"({"op": "ping", "id": )" + nested("[", "]", kMaxRequestDepth - 1) + "}";
  SocketRequest request;
  std::string error;
  EXPECT_TRUE(parse_socket_request(header, ProtocolLimits{}, request, error)) << error;
  EXPECT_TRUE(request.id.is_array());
}

// The same request through the real server: answered "bad_request", the server lives on.
TEST(ProtocolRegression, ServerAnswersADeeplyNestedRequestAndKeepsServing) {
  const fs::path dir = fs::temp_directory_path() / ("ssdo-protocol-regression-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "out");
  fs::create_directories(dir / "spool");
  FrameServiceOptions frame_options;
  frame_options.out_dir = (dir / "out").string();
  frame_options.workers = 0;
  frame_options.queue_capacity = 0;
  FrameService frames(frame_options);
  frames.start();
  SocketServerOptions options;
  options.path = (dir / "s").string();
  options.allow_roots = {dir.string()};
  options.out_dir = (dir / "out").string();
  options.spool_dir = (dir / "spool").string();
  options.limits.max_header_bytes = size_t(1) << 20;
  options.client_timeout_s = 10;
  {
    SocketServer server(options, frames);
    std::string error;
    ASSERT_TRUE(server.bind(error)) << error;
    server.start();
    auto ask = [&](const std::string& header) {
      const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
      sockaddr_un addr{};
      addr.sun_family = AF_UNIX;
      std::strncpy(addr.sun_path, options.path.c_str(), sizeof addr.sun_path - 1);
      EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
      EXPECT_EQ(write_message(fd, header, deadline_in(10)), IoStatus::ok);
      std::string reply;
      EXPECT_EQ(read_message(fd, reply, size_t(1) << 20, deadline_in(10)), IoStatus::ok);
      ::close(fd);
      return nlohmann::json::parse(reply, nullptr, false);
    };
    const nlohmann::json refused = ask(R"({"op": "ping", "id": )" + nested("[", "]", 500000) + "}");
    EXPECT_EQ(refused.value("code", ""), "bad_request");
    const nlohmann::json pong = ask(R"({"op": "ping", "id": 3})");
    EXPECT_EQ(pong.value("ok", false), true);
    EXPECT_EQ(pong.value("id", 0), 3);
    server.stop();
  }
  frames.stop();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ssdo
