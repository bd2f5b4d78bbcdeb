// Length-prefixed JSON messages, as spoken on the worker pipes and on the service socket.
//
// A message is a 4-byte big-endian unsigned length N followed by N bytes of UTF-8 JSON
// (one object). A message whose JSON has "inline_size": K (K > 0) is followed directly by
// K raw bytes (an EXR file): no base64, no second length. See docs/service.md, "Wire protocol".
//
// All I/O takes an absolute deadline and works on blocking and non-blocking descriptors
// alike (poll() before every read and write), so a silent peer costs at most its deadline.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace ssdo {

using Clock = std::chrono::steady_clock;
using Deadline = Clock::time_point;

inline Deadline no_deadline() { return Deadline::max(); }
inline Deadline deadline_in(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

enum class IoStatus {
  ok,
  closed,     // the peer closed before the first byte of a message (a clean end)
  truncated,  // the peer closed in the middle of a message
  timeout,    // the deadline passed
  too_large,  // the length prefix exceeds the limit (nothing of the body was read)
  error,      // any other failure (errno text in the caller's hands)
};
const char* to_string(IoStatus status);

IoStatus read_exact(int fd, void* data, size_t size, Deadline deadline);
IoStatus write_all(int fd, const void* data, size_t size, Deadline deadline);

// Waits until `fd` has bytes to read (or is closed) for at most `seconds` of the time this
// process runs: it wakes every second, and a wake that returns later than asked counts
// only the time asked: the rest is time the process was stopped (SIGSTOP, a farm's
// suspension of the job), so a suspended batch does not time out the frames in flight
// when it resumes.
IoStatus wait_readable_running(int fd, double seconds);

// One length-prefixed message of at most `max_bytes` bytes.
IoStatus read_message(int fd, std::string& message, size_t max_bytes, Deadline deadline);
IoStatus write_message(int fd, std::string_view message, Deadline deadline);

// Reads and drops what arrives until the other end closes (closed), the read fails or the
// deadline passes (timeout; a deadline already past: one read, without waiting): a
// connection ended after its answer, so that the client's sending does not fail before it
// reads that answer.
IoStatus drain_input(int fd, Deadline deadline);

// Reads and discards `size` bytes (an unwanted inline payload), so the stream stays in step.
IoStatus skip_bytes(int fd, size_t size, Deadline deadline);

// The 4-byte big-endian length prefix of a message of `size` bytes, and its inverse.
void encode_length(uint32_t size, unsigned char out[4]);
uint32_t decode_length(const unsigned char in[4]);

// The socket protocol's revision, sent in the "ping" reply as "protocol". It grows when a
// request or reply changes in a way an existing client would misread (a field removed or
// its meaning changed); added optional fields and ops keep it. docs/service.md, "Versioning".
constexpr int kProtocolVersion = 1;

// Limits of the service socket. Defaults are generous for film frames and small enough
// that 16 clients at the limit fit in memory.
struct ProtocolLimits {
  size_t max_header_bytes = size_t(1) << 20;        // JSON of one request: 1 MiB
  size_t max_inline_bytes = size_t(512) << 20;      // EXR bytes of one request: 512 MiB
};

// A socket request after validation (docs/service.md, "Wire protocol").
struct SocketRequest {
  std::string op;                // "ping" | "stats" | "process"
  nlohmann::json id;             // echoed back when given (any JSON value)
  std::string input;             // process by path: the input EXR
  size_t inline_size = 0;        // process inline: bytes following the header
  std::string name = "inline";   // inline input: the frame's name (file name stem)
  nlohmann::json sidecar;        // inline input: the camera sidecar object, or null
  std::string output;            // explicit output path (under --out); empty = OUT/NAME.ssdo.exr
  bool reply_inline = false;     // return the output EXR bytes instead of its path
  nlohmann::json options;        // frame options (the CLI flag names), an object
  std::vector<std::string> views;  // neighbour frames of the same shot (extra views with "views" > 0)
};

// Most neighbour frames a request may name (twice the largest --views).
constexpr size_t kMaxRequestViews = 16;

// Deepest nesting of arrays and objects a request header may have (a sidecar needs 3).
constexpr int kMaxRequestDepth = 64;

// Parses and validates a request header. False with a message naming the field.
bool parse_socket_request(std::string_view header, const ProtocolLimits& limits, SocketRequest& request,
                          std::string& error);

// True for a name usable as a file stem: [A-Za-z0-9._-]{1,128}, not starting with '.'.
bool is_safe_name(std::string_view name);
// A safe name (is_safe_name) for a file stem: other characters become '_', a leading '.'
// or an empty stem gets an 'f' before it, at most 128 characters.
std::string safe_name_for(std::string_view stem);

// The JSON text of a message. Strings from damaged files (channel names, attribute
// values) may hold invalid UTF-8: such bytes become U+FFFD instead of failing.
std::string to_wire(const nlohmann::json& j);

// {"ok": false, "error": message, "code": code} (+ "id" when given).
nlohmann::json error_response(const std::string& code, const std::string& message,
                              const nlohmann::json& id = nullptr);

// `text` with its control characters (C0, DEL) written as \n, \t, \r or \xNN, for a
// log line or a message: a file name holding a newline cannot forge a line of its own.
std::string printable(const std::string& text);

}  // namespace ssdo
