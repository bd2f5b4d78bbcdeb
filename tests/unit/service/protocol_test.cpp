#include <fcntl.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <thread>

#include <gtest/gtest.h>

#include "service/protocol.h"

namespace ssdo {
namespace {

struct SocketPair {
  int a = -1, b = -1;
  SocketPair() {
    int fds[2];
    EXPECT_EQ(::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds), 0);
    a = fds[0];
    b = fds[1];
  }
  ~SocketPair() {
    if (a >= 0) ::close(a);
    if (b >= 0) ::close(b);
  }
};

TEST(Framing, LengthIsFourBytesBigEndian) {
  unsigned char p[4];
  encode_length(0x01020304u, p);
  EXPECT_EQ(p[0], 1);
  EXPECT_EQ(p[3], 4);
  EXPECT_EQ(decode_length(p), 0x01020304u);
}

TEST(Framing, MessagesRoundTripInOrder) {
  SocketPair s;
  ASSERT_EQ(write_message(s.a, R"({"op":"ping"})", deadline_in(1)), IoStatus::ok);
  ASSERT_EQ(write_message(s.a, "", deadline_in(1)), IoStatus::ok);
  std::string m;
  ASSERT_EQ(read_message(s.b, m, 1024, deadline_in(1)), IoStatus::ok);
  EXPECT_EQ(m, R"({"op":"ping"})");
  ASSERT_EQ(read_message(s.b, m, 1024, deadline_in(1)), IoStatus::ok);
  EXPECT_EQ(m, "");
}

TEST(Framing, OversizeIsRefusedFromTheLengthAlone) {
  SocketPair s;
  ASSERT_EQ(write_message(s.a, std::string(2000, 'x'), deadline_in(1)), IoStatus::ok);
  std::string m;
  EXPECT_EQ(read_message(s.b, m, 1000, deadline_in(1)), IoStatus::too_large);
  EXPECT_TRUE(m.empty());
}

TEST(Framing, SilencePartialAndClosedPeersAreTold) {
  SocketPair s;
  std::string m;
  const auto t0 = Clock::now();
  EXPECT_EQ(read_message(s.b, m, 1000, deadline_in(0.05)), IoStatus::timeout);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 1.0);
  unsigned char prefix[4];
  encode_length(10, prefix);
  ASSERT_EQ(write_all(s.a, prefix, 4, deadline_in(1)), IoStatus::ok);
  ASSERT_EQ(write_all(s.a, "abc", 3, deadline_in(1)), IoStatus::ok);
  EXPECT_EQ(read_message(s.b, m, 1000, deadline_in(0.05)), IoStatus::timeout);  // 7 bytes missing
  ::close(s.a);
  s.a = -1;
  EXPECT_EQ(read_message(s.b, m, 1000, deadline_in(1)), IoStatus::closed);
}

// The time a process is stopped (SIGSTOP: a farm suspending the job) is not a wait's: a
// child waiting 3 s for a reply, stopped for 4 s, still takes the reply sent after it
// resumes; one that is not stopped times out in about its 3 s.
TEST(Framing, AWaitDoesNotCountTheTimeItsProcessWasStopped) {
  auto child_waits = [](int fd) {
    const pid_t pid = ::fork();
    if (pid == 0) _exit(wait_readable_running(fd, 3.0) == IoStatus::ok ? 0 : 1);
    return pid;
  };
  auto exit_code = [](pid_t pid) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  SocketPair s;
  const pid_t stopped = child_waits(s.b);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ::kill(stopped, SIGSTOP);
  std::this_thread::sleep_for(std::chrono::seconds(4));
  ::kill(stopped, SIGCONT);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ASSERT_EQ(::write(s.a, "x", 1), 1);
  EXPECT_EQ(exit_code(stopped), 0);
  SocketPair quiet;
  const auto t0 = Clock::now();
  EXPECT_EQ(exit_code(child_waits(quiet.b)), 1);
  const double waited_s = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_GT(waited_s, 2.9);
  EXPECT_LT(waited_s, 8.0);
}

TEST(Framing, TruncatedMessageIsNotAClean_end) {
  SocketPair s;
  unsigned char prefix[4];
  encode_length(10, prefix);
  ASSERT_EQ(write_all(s.a, prefix, 4, deadline_in(1)), IoStatus::ok);
  ASSERT_EQ(write_all(s.a, "abc", 3, deadline_in(1)), IoStatus::ok);
  ::close(s.a);
  s.a = -1;
  std::string m;
  EXPECT_EQ(read_message(s.b, m, 1000, deadline_in(1)), IoStatus::truncated);
}

TEST(Framing, InvalidUtf8FromDamagedFilesIsReplacedNotThrown) {
  nlohmann::json j{{"error", std::string("channel \xff\xfe name")}};
  std::string wire;
  ASSERT_NO_THROW(wire = to_wire(j));
  EXPECT_FALSE(nlohmann::json::parse(wire, nullptr, false).is_discarded());
}

SocketRequest parse_ok(const std::string& text, const ProtocolLimits& limits = {}) {
  SocketRequest r;
  std::string error;
  EXPECT_TRUE(parse_socket_request(text, limits, r, error)) << text << ": " << error;
  return r;
}

std::string parse_error(const std::string& text, const ProtocolLimits& limits = {}) {
  SocketRequest r;
  std::string error;
  EXPECT_FALSE(parse_socket_request(text, limits, r, error)) << text;
  return error;
}

TEST(SocketRequest, PingStatsAndProcessByPathOrInline) {
  EXPECT_EQ(parse_ok(R"({"op":"ping","id":7})").id, 7);
  EXPECT_EQ(parse_ok(R"({"op":"stats"})").op, "stats");
  const SocketRequest p = parse_ok(R"({"op":"process","input":"/a/b.exr","options":{"terms":"ao"}})");
  EXPECT_EQ(p.input, "/a/b.exr");
  EXPECT_EQ(p.inline_size, 0u);
  EXPECT_FALSE(p.reply_inline);
  EXPECT_EQ(p.options["terms"], "ao");
  const SocketRequest i =
      parse_ok(R"({"op":"process","inline_size":1234,"name":"shot.0001","reply":"inline","sidecar":{"fov":50}})");
  EXPECT_EQ(i.inline_size, 1234u);
  EXPECT_EQ(i.name, "shot.0001");
  EXPECT_TRUE(i.reply_inline);
  EXPECT_TRUE(i.sidecar.is_object());
}

TEST(SocketRequest, MalformedRequestsNameTheProblem) {
  EXPECT_NE(parse_error("not json").find("JSON"), std::string::npos);
  EXPECT_NE(parse_error("[1,2]").find("object"), std::string::npos);
  EXPECT_NE(parse_error(R"({"input":"x"})").find("op"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"fly"})").find("fly"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"ping","input":"x"})").find("ping"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process"})").find("exactly one"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":"a","inline_size":3})").find("exactly one"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":""})").find("input"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","inline_size":-1})").find("inline_size"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","inline_size":0})").find("inline_size"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":"a","reply":"email"})").find("reply"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":"a","options":"fast"})").find("options"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":"a","colour":1})").find("colour"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":"a","name":"x"})").find("inline"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","inline_size":5,"name":"../x"})").find("name"), std::string::npos);
  EXPECT_NE(parse_error(R"({"op":"process","input":"a","output":"/o/x.exr","reply":"inline"})").find("exclude"),
            std::string::npos);  // A NUL ends the path for the system: "/o/notes.txt\0.exr" would pass as an .exr name.
  EXPECT_EQ(parse_error(R"({"op":"process","input":"a","output":"/o/notes.txt\u0000.exr"})"),
            "\"output\" holds a NUL byte");
  EXPECT_EQ(parse_error(R"({"op":"process","input":"a\u0000b"})"), "\"input\" holds a NUL byte");
}

TEST(SocketRequest, InlineSizeHasALimit) {
  ProtocolLimits limits;
  limits.max_inline_bytes = 1000;
  parse_ok(R"({"op":"process","inline_size":1000})", limits);
  EXPECT_NE(parse_error(R"({"op":"process","inline_size":1001})", limits).find("limit"), std::string::npos);
}

TEST(SocketRequest, SafeNamesArePlainStems) {
  EXPECT_TRUE(is_safe_name("shot.0001"));
  EXPECT_TRUE(is_safe_name("a-b_c"));
  for (const char* bad : {"", ".hidden", "a/b", "..", "a b", "x\n"}) EXPECT_FALSE(is_safe_name(bad)) << bad;
  EXPECT_FALSE(is_safe_name(std::string(129, 'a')));
  // What the client sends for a file stem that is none.
  EXPECT_EQ(safe_name_for("shot.0001"), "shot.0001");
  EXPECT_EQ(safe_name_for("shot A \xc3\xbc"), "shot_A___");
  EXPECT_EQ(safe_name_for(".hidden"), "f.hidden");
  EXPECT_EQ(safe_name_for(""), "f");
  EXPECT_EQ(safe_name_for(std::string(300, 'a')), std::string(127, 'a'));
  for (const char* stem : {"a/b", "..", "x\n", "-dash"}) EXPECT_TRUE(is_safe_name(safe_name_for(stem))) << stem;
}

TEST(SocketRequest, ErrorResponsesCarryCodeMessageAndId) {
  const auto j = error_response("busy", "queue full", 42);
  EXPECT_EQ(j["ok"], false);
  EXPECT_EQ(j["code"], "busy");
  EXPECT_EQ(j["error"], "queue full");
  EXPECT_EQ(j["id"], 42);
  EXPECT_FALSE(error_response("x", "y").contains("id"));
}

}  // namespace
}  // namespace ssdo
