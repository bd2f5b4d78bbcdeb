#include "service/protocol.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <vector>

namespace ssdo {

namespace {

// Waits until `fd` is ready for `events` or the deadline passes.
IoStatus wait_ready(int fd, short events, Deadline deadline) {
  for (;;) {
    int timeout_ms = -1;
    if (deadline != Deadline::max()) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) return IoStatus::timeout;
      timeout_ms = int(std::min<long long>(left, 1 << 30));
    }
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, timeout_ms);
    if (n > 0) return IoStatus::ok;  // ready, or an error/hang-up the next call reports
    if (n == 0) return IoStatus::timeout;
    if (errno != EINTR) return IoStatus::error;
  }
}

}  // namespace

IoStatus wait_readable_running(int fd, double seconds) {
  using std::chrono::duration;
  constexpr int kWakeMs = 1000;
  double counted_s = 0.0;
  for (;;) {
    const double left_s = seconds - counted_s;
    if (left_s <= 0.0) return IoStatus::timeout;
    pollfd p{fd, POLLIN, 0};
    const int wake_ms = int(std::min(double(kWakeMs), std::ceil(left_s * 1000.0)));
    const Clock::time_point before = Clock::now();
    const int n = ::poll(&p, 1, wake_ms);
    // At most the wake's own time: more is time the process was stopped.
    counted_s += std::min(duration<double>(Clock::now() - before).count(), 1e-3 * wake_ms);
    if (n > 0) return IoStatus::ok;  // bytes, or a hang-up the read reports
    if (n < 0 && errno != EINTR) return IoStatus::error;
  }
}

const char* to_string(IoStatus status) {
  switch (status) {
    case IoStatus::ok: return "ok";
    case IoStatus::closed: return "connection closed";
    case IoStatus::truncated: return "connection closed in the middle of a message";
    case IoStatus::timeout: return "timed out";
    case IoStatus::too_large: return "message too large";
    case IoStatus::error: return "I/O error";
  }
  return "?";
}

IoStatus read_exact(int fd, void* data, size_t size, Deadline deadline) {
  char* p = static_cast<char*>(data);
  size_t done = 0;
  while (done < size) {
    if (const IoStatus s = wait_ready(fd, POLLIN, deadline); s != IoStatus::ok) return s;
    const ssize_t n = ::read(fd, p + done, size - done);
    if (n > 0) {
      done += size_t(n);
    } else if (n == 0) {
      return done == 0 ? IoStatus::closed : IoStatus::truncated;
    } else if (errno != EINTR && errno != EAGAIN && errno != EWOULDBLOCK) {
      return errno == ECONNRESET ? IoStatus::truncated : IoStatus::error;
    }
  }
  return IoStatus::ok;
}

IoStatus write_all(int fd, const void* data, size_t size, Deadline deadline) {
  const char* p = static_cast<const char*>(data);
  size_t done = 0;
  while (done < size) {
    if (const IoStatus s = wait_ready(fd, POLLOUT, deadline); s != IoStatus::ok) return s;
    // send() with MSG_NOSIGNAL on sockets; write() on pipes (SIGPIPE is ignored by the
    // processes that write to pipes: the batch, the service and the workers).
    ssize_t n = ::send(fd, p + done, size - done, MSG_NOSIGNAL);
    if (n < 0 && errno == ENOTSOCK) n = ::write(fd, p + done, size - done);
    if (n > 0) {
      done += size_t(n);
    } else if (n < 0 && errno != EINTR && errno != EAGAIN && errno != EWOULDBLOCK) {
      return (errno == EPIPE || errno == ECONNRESET) ? IoStatus::closed : IoStatus::error;
    }
  }
  return IoStatus::ok;
}

void encode_length(uint32_t size, unsigned char out[4]) {
  out[0] = static_cast<unsigned char>(size >> 24);
  out[1] = static_cast<unsigned char>(size >> 16);
  out[2] = static_cast<unsigned char>(size >> 8);
  out[3] = static_cast<unsigned char>(size);
}

uint32_t decode_length(const unsigned char in[4]) {
  return (uint32_t(in[0]) << 24) | (uint32_t(in[1]) << 16) | (uint32_t(in[2]) << 8) | uint32_t(in[3]);
}

IoStatus read_message(int fd, std::string& message, size_t max_bytes, Deadline deadline) {
  unsigned char prefix[4];
  if (const IoStatus s = read_exact(fd, prefix, 4, deadline); s != IoStatus::ok) return s;
  const uint32_t size = decode_length(prefix);
  if (size > max_bytes) return IoStatus::too_large;
  message.resize(size);
  const IoStatus s = read_exact(fd, message.data(), size, deadline);
  return s == IoStatus::closed ? IoStatus::truncated : s;
}

IoStatus write_message(int fd, std::string_view message, Deadline deadline) {
  if (message.size() > 0xffffffffu) return IoStatus::too_large;
  std::string framed(4, '\0');
  encode_length(uint32_t(message.size()), reinterpret_cast<unsigned char*>(framed.data()));
  framed.append(message);
  return write_all(fd, framed.data(), framed.size(), deadline);
}

IoStatus drain_input(int fd, Deadline deadline) {
  char sink[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, sink, sizeof sink);
    const int error = n < 0 ? errno : 0;
    if (n == 0) return IoStatus::closed;
    if (n < 0 && error != EINTR && error != EAGAIN && error != EWOULDBLOCK) return IoStatus::error;
    if (Clock::now() >= deadline) return IoStatus::timeout;  // a client that keeps sending
    if (n < 0 && error != EINTR)
      if (const IoStatus s = wait_ready(fd, POLLIN, deadline); s != IoStatus::ok) return s;
  }
}

IoStatus skip_bytes(int fd, size_t size, Deadline deadline) {
  std::vector<char> sink(std::min<size_t>(size, 1 << 16));
  while (size > 0) {
    const size_t n = std::min(size, sink.size());
    const IoStatus s = read_exact(fd, sink.data(), n, deadline);
    if (s != IoStatus::ok) return s == IoStatus::closed ? IoStatus::truncated : s;
    size -= n;
  }
  return IoStatus::ok;
}

bool is_safe_name(std::string_view name) {
  if (name.empty() || name.size() > 128 || name[0] == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
  });
}

std::string safe_name_for(std::string_view stem) {
  std::string name(stem.substr(0, 127));
  for (char& c : name)
    if (!is_safe_name(std::string("f") + c)) c = '_';
  if (name.empty() || name[0] == '.') name.insert(0, "f");
  return name;
}

namespace {

// The request header as JSON. nlohmann::json copies and dumps values recursively: a deeply
// nested "id", "sidecar" or "options" (a 1 MiB header holds 500,000 levels) would overflow
// the connection thread's stack and end the whole service. The parser itself is iterative;
// the depth is checked while parsing, before any copy.
bool parse_header(std::string_view header, nlohmann::json& j, std::string& error) {
  bool too_deep = false;
  j = nlohmann::json::parse(
      header,
      [&](int depth, nlohmann::json::parse_event_t, nlohmann::json&) {
        if (depth > kMaxRequestDepth) too_deep = true;
        return !too_deep;
      },
      false);
  if (too_deep) {
    error = "the request nests deeper than " + std::to_string(kMaxRequestDepth) + " levels";
    return false;
  }
  if (j.is_discarded()) {
    error = "the request is not valid JSON";
    return false;
  }
  if (!j.is_object()) {
    error = "the request must be a JSON object";
    return false;
  }
  return true;
}

// "op" and "id", and no field the protocol does not know.
bool parse_op(const nlohmann::json& j, SocketRequest& r, std::string& error) {
  if (j.contains("id")) r.id = j["id"];
  const auto op = j.find("op");
  if (op == j.end() || !op->is_string()) {
    error = "\"op\" is missing or not a string (ping, stats, process)";
    return false;
  }
  r.op = op->get<std::string>();
  static const char* kKeys[] = {"op",     "id",    "input",   "inline_size", "name",
                                "sidecar", "output", "reply", "options",     "views"};
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (std::find_if(std::begin(kKeys), std::end(kKeys), [&](const char* k) { return it.key() == k; }) ==
        std::end(kKeys)) {
      error = "unknown request field \"" + it.key() + "\"";
      return false;
    }
  }
  return true;
}

// A process request's input: "input" (a path), or "inline_size" bytes after the header
// with an optional "name" and camera "sidecar".
bool parse_input(const nlohmann::json& j, const ProtocolLimits& limits, SocketRequest& r, std::string& error) {
  const bool has_input = j.contains("input"), has_inline = j.contains("inline_size");
  if (has_input == has_inline) {
    error = "process: give exactly one of \"input\" (a path) and \"inline_size\" (bytes that follow)";
    return false;
  }
  if (has_input) {
    if (!j["input"].is_string() || j["input"].get<std::string>().empty()) {
      error = "\"input\" must be a non-empty path string";
      return false;
    }
    r.input = j["input"].get<std::string>();
    if (r.input.find('\0') != std::string::npos) {
      error = "\"input\" holds a NUL byte";
      return false;
    }
    if (j.contains("name") || j.contains("sidecar")) {
      error = "\"name\" and \"sidecar\" go with inline input only";
      return false;
    }
  } else {
    const nlohmann::json& n = j["inline_size"];
    if (!n.is_number_unsigned() || n.get<uint64_t>() == 0) {
      error = "\"inline_size\" must be a positive integer (bytes of the EXR after the header)";
      return false;
    }
    if (n.get<uint64_t>() > limits.max_inline_bytes) {
      error = "\"inline_size\" " + std::to_string(n.get<uint64_t>()) + " exceeds the limit of " +
              std::to_string(limits.max_inline_bytes) + " bytes";
      return false;
    }
    r.inline_size = size_t(n.get<uint64_t>());
    if (j.contains("name")) {
      if (!j["name"].is_string() || !is_safe_name(j["name"].get<std::string>())) {
        error =
            "\"name\" must be a plain file stem: letters, digits, '.', '_', '-' (at most 128, not starting with '.')";
        return false;
      }
      r.name = j["name"].get<std::string>();
    }
    if (j.contains("sidecar")) {
      if (!j["sidecar"].is_object()) {
        error = "\"sidecar\" must be a camera sidecar JSON object";
        return false;
      }
      r.sidecar = j["sidecar"];
    }
  }
  return true;
}

// Where the output goes ("output", "reply") and the frame options, an object checked
// against the option table by the service (apply_json, request_options.h).
bool parse_output(const nlohmann::json& j, SocketRequest& r, std::string& error) {
  if (j.contains("output")) {
    if (!j["output"].is_string() || j["output"].get<std::string>().empty()) {
      error = "\"output\" must be a non-empty path string";
      return false;
    }
    r.output = j["output"].get<std::string>();
    if (r.output.find('\0') != std::string::npos) {
      error = "\"output\" holds a NUL byte";
      return false;
    }
  }
  if (j.contains("reply")) {
    const nlohmann::json& reply = j["reply"];
    if (!reply.is_string() || (reply != "path" && reply != "inline")) {
      error = "\"reply\" must be \"path\" or \"inline\"";
      return false;
    }
    r.reply_inline = reply == "inline";
  }
  if (r.reply_inline && !r.output.empty()) {
    error = "\"output\" and \"reply\": \"inline\" exclude each other";
    return false;
  }
  if (j.contains("options")) {
    if (!j["options"].is_object()) {
      error = "\"options\" must be an object of frame options";
      return false;
    }
    r.options = j["options"];
  } else {
    r.options = nlohmann::json::object();
  }
  return true;
}

// "views": neighbour frames of the same shot, paths the service confines like "input".
bool parse_views(const nlohmann::json& j, SocketRequest& r, std::string& error) {
  if (!j.contains("views")) return true;
  const nlohmann::json& v = j["views"];
  const bool paths = v.is_array() && std::all_of(v.begin(), v.end(), [](const nlohmann::json& p) {
    return p.is_string() && !p.get<std::string>().empty() && p.get<std::string>().find('\0') == std::string::npos;
  });
  if (!paths || v.size() > kMaxRequestViews) {
    error = "\"views\" must be a list of at most " + std::to_string(kMaxRequestViews) + " non-empty path strings";
    return false;
  }
  r.views = v.get<std::vector<std::string>>();
  return true;
}

}  // namespace

bool parse_socket_request(std::string_view header, const ProtocolLimits& limits, SocketRequest& r,
                          std::string& error) {
  nlohmann::json j;
  if (!parse_header(header, j, error)) return false;
  r = SocketRequest{};
  if (!parse_op(j, r, error)) return false;
  if (r.op == "ping" || r.op == "stats") {
    if (j.size() > (j.contains("id") ? 2u : 1u)) {
      error = "\"" + r.op + "\" takes no fields besides \"id\"";
      return false;
    }
    return true;
  }
  if (r.op != "process") {
    error = "unknown op \"" + r.op + "\" (ping, stats, process)";
    return false;
  }
  return parse_input(j, limits, r, error) && parse_output(j, r, error) && parse_views(j, r, error);
}

std::string to_wire(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

nlohmann::json error_response(const std::string& code, const std::string& message, const nlohmann::json& id) {
  nlohmann::json j{{"ok", false}, {"code", code}, {"error", printable(message)}};
  if (!id.is_null()) j["id"] = id;
  return j;
}

std::string printable(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u != 0x7f) {
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\r') {
      out += "\\r";
    } else {
      static const char hex[] = "0123456789abcdef";
      out += "\\x";
      out += hex[u >> 4];
      out += hex[u & 15];
    }
  }
  return out;
}

}  // namespace ssdo
