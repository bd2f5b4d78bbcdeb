#include "service/socket_server.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <memory>
#include <system_error>
#include <vector>

#include "formats/output_writer.h"
#include "service/frame_list.h"
#include "service/frame_options.h"
#include "service/path_policy.h"
#include "service/request_options.h"
#include "service/sequence.h"
#include "service/version.h"

namespace ssdo {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// A request's spool folder, and the spool itself when it is gone (removed by hand, say):
// private to the service, as cmd_serve creates it.
void make_spool_folder(const fs::path& folder, std::error_code& ec) {
  const fs::path spool = folder.parent_path();
  if (!fs::is_directory(spool, ec)) make_private_folder(spool, ec);
  fs::create_directory(folder, ec);
}

// How often a connection waiting for its frame checks that its client is still there, ms.
constexpr int kPeerCheckMs = 250;

// Whether the client has closed its end of the connection (both directions: a client that
// only shut down its sending side still reads the reply).
bool peer_closed(int fd) {
  pollfd p{fd, 0, 0};  // POLLHUP and POLLERR are reported whatever is asked
  return ::poll(&p, 1, 0) > 0 && (p.revents & (POLLHUP | POLLERR)) != 0;
}

// How long an over-limit client gets to read its "busy" answer before it is closed.
constexpr double kBusyReplySeconds = 0.5;
// How long a connection the service ends after answering (at accept: "busy"; later:
// too_large, timeout, a request refused before its inline bytes were read) stays open, its
// input read and dropped, before it is closed: long enough for its client to finish
// sending (sending to a closed connection fails, and a client that stops there never reads
// the answer). At most kMaxAnsweredOpen connections answered at accept wait at once; the
// oldest is closed for a new one.
constexpr double kAnsweredOpenSeconds = 1.0;
constexpr size_t kMaxAnsweredOpen = 32;
// How long stop() waits for connections to finish their request, beyond the deadlines
// they already have.
constexpr double kStopMarginSeconds = 5;
// How long, once the service stops, a reply may wait for its client to take it: a local
// client that reads takes even a 1080p frame inline in well under a second.
constexpr double kStopReplyGraceSeconds = 5;
// How often stop() looks for replies past that grace.
constexpr double kStopCheckSeconds = 0.25;
// Request headers held at once (being read, or parsed and waiting for their frame), in
// units of --max-request-bytes: a parsed JSON header takes several times its bytes, and
// 16 at the 1 MiB default stay within a few hundred MiB.
constexpr size_t kHeaderBudgetRequests = 16;
// Headers this small (a ping, stats, a process request by path) are outside the budget, so
// clients sending large ones cannot keep them out; at most --max-clients of them at once.
constexpr size_t kSmallHeaderBytes = 4096;

// Waits until `fd` has a byte to read (or its end), at most until `deadline`.
IoStatus wait_for_request(int fd, Deadline deadline) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return IoStatus::timeout;
    pollfd p{fd, POLLIN, 0};
    const int n = ::poll(&p, 1, int(std::min<long long>(left, 1 << 30)));
    if (n > 0) return IoStatus::ok;
    if (n < 0 && errno != EINTR) return IoStatus::error;
  }
}

bool stream_to_file(int socket_fd, const std::string& path, size_t size, Deadline deadline, std::string& error) {
  const int out = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (out < 0) {
    error = "cannot create a spool file: " + std::string(std::strerror(errno));
    return false;
  }
  std::vector<char> buffer(std::min<size_t>(size, size_t(1) << 20));
  bool ok = true;
  while (size > 0 && ok) {
    const size_t n = std::min(size, buffer.size());
    const IoStatus s = read_exact(socket_fd, buffer.data(), n, deadline);
    if (s != IoStatus::ok) {
      error = std::string("inline frame: ") + to_string(s == IoStatus::closed ? IoStatus::truncated : s);
      ok = false;
      break;
    }
    for (size_t done = 0; done < n;) {
      const ssize_t w = ::write(out, buffer.data() + done, n - done);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        error = "cannot write a spool file: " + std::string(std::strerror(errno));
        ok = false;
        break;
      }
      done += size_t(w);
    }
    size -= n;
  }
  ::close(out);
  return ok;
}

json stats_json(const ServiceStats& s, int clients) {
  return json{{"ok", true},
              {"op", "stats"},
              {"frames_done", s.frames_done},
              {"frames_failed", s.frames_failed},
              {"frames_skipped", s.frames_skipped},
              {"queue_depth", s.queue_depth},
              {"queue_capacity", s.queue_capacity},
              {"in_flight", s.in_flight},
              {"mean_frame_ms", s.mean_frame_ms},
              {"workers", s.workers},
              {"workers_replaced", s.workers_replaced},
              {"frames_retried", s.frames_retried},
              {"clients", clients},
              {"uptime_s", s.uptime_s}};
}

}  // namespace

SocketServer::SocketServer(SocketServerOptions options, FrameService& frames)
    : options_(std::move(options)), frames_(frames) {}

SocketServer::~SocketServer() { stop(); }

bool SocketServer::bind(std::string& error) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (options_.path.empty() || options_.path.size() >= sizeof addr.sun_path) {
    error = "--socket " + options_.path + ": the path must be 1 to " + std::to_string(sizeof addr.sun_path - 1) +
            " bytes long";
    return false;
  }
  std::memcpy(addr.sun_path, options_.path.c_str(), options_.path.size() + 1);
  struct stat st {};
  if (::lstat(options_.path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      error = "--socket " + options_.path + ": exists and is not a socket";
      return false;
    }
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live = ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    ::close(probe);
    if (live) {
      error = "--socket " + options_.path + ": another service is listening on it";
      return false;
    }
    ::unlink(options_.path.c_str());  // stale: its service is gone
  }
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listen_fd_ < 0) {
    error = std::string("socket: ") + std::strerror(errno);
    return false;
  }
  // Created without group/other access, then set to the requested mode: no moment where
  // others could connect. (umask is process-wide: this runs before any other thread.)
  const mode_t old_mask = ::umask(0177);
  const int rc = ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  const int bind_errno = errno;
  ::umask(old_mask);
  if (rc != 0) {
    error = "--socket " + options_.path + ": " + std::strerror(bind_errno);
    return false;
  }
  struct stat bound {};
  if (::lstat(options_.path.c_str(), &bound) == 0) {
    socket_dev_ = bound.st_dev;
    socket_ino_ = bound.st_ino;
  }
  if (::chmod(options_.path.c_str(), options_.mode) != 0 || ::listen(listen_fd_, 128) != 0 ||
      ::pipe2(stop_pipe_, O_CLOEXEC | O_NONBLOCK) != 0) {
    error = "--socket " + options_.path + ": " + std::strerror(errno);
    unlink_own_socket();
    return false;
  }
  return true;
}

void SocketServer::unlink_own_socket() {
  // The path may have been removed and bound again by another instance since: the file is
  // ours only while it is the inode bind() created (stat(2) st_dev + st_ino).
  struct stat now {};
  if (::lstat(options_.path.c_str(), &now) == 0 && now.st_dev == socket_dev_ && now.st_ino == socket_ino_)
    ::unlink(options_.path.c_str());
}

void SocketServer::start() { accept_thread_ = std::thread([this] { accept_loop(); }); }

void SocketServer::stop_accepting() {
  if (accept_thread_.joinable()) {
    const char c = 's';
    (void)!::write(stop_pipe_[1], &c, 1);
    accept_thread_.join();
  }
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
    unlink_own_socket();
  }
}

void SocketServer::stop() {
  stop_accepting();
  std::unique_lock<std::mutex> lock(mutex_);
  stopping_ = true;
  // Wake connections waiting for a request; one inside a request finishes it (its reply
  // can still be written) and then sees the end of its input.
  for (const auto& [fd, connection] : connections_) ::shutdown(fd, SHUT_RD);
  const Clock::time_point stop_time = Clock::now();
  const auto until = stop_time + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(options_.client_timeout_s + kStopMarginSeconds));
  while (!connections_.empty() && Clock::now() < until) {
    cut_stalled_replies(stop_time);
    all_closed_.wait_for(lock, std::chrono::duration<double>(kStopCheckSeconds), [&] { return connections_.empty(); });
  }
  lock.unlock();
  for (int* fd : {&stop_pipe_[0], &stop_pipe_[1]})
    if (*fd >= 0) {
      ::close(*fd);
      *fd = -1;
    }
}

namespace {

// Connections answered at accept, open until their client has sent and closed or until
// kAnsweredOpenSeconds have passed (see there).
// Allocates nothing after its construction (the accept loop runs on when memory is short).
class AnsweredConnections {
 public:
  AnsweredConnections() { open_.reserve(kMaxAnsweredOpen); }
  ~AnsweredConnections() {
    for (const Entry& e : open_) ::close(e.fd);
  }
  // Keeps fd open for a while.
  void add(int fd) {
    if (open_.size() >= kMaxAnsweredOpen) close_at(0);
    open_.push_back({fd, Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                            std::chrono::duration<double>(kAnsweredOpenSeconds))});
  }
  // Their pollfds, appended to `fds` (room for kMaxAnsweredOpen reserved); the poll
  // timeout until the first deadline (-1: none).
  int watch(std::vector<pollfd>& fds) const {
    for (const Entry& e : open_) fds.push_back({e.fd, POLLIN, 0});
    if (open_.empty()) return -1;
    const auto wait = open_.front().until - Clock::now();
    return int(std::clamp<int64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(wait).count() + 1, 0, 1000));
  }
  // After the poll: drops what arrived, closes those whose client closed or whose time is up.
  void service(const pollfd* polled) {
    const Clock::time_point now = Clock::now();
    for (size_t i = open_.size(); i-- > 0;)  // from the back: erasing keeps the earlier indices
      if (now >= open_[i].until || (polled[i].revents != 0 && !drain_round(open_[i].fd))) close_at(i);
  }

 private:
  struct Entry {
    int fd;
    Clock::time_point until;
  };
  // Reads and drops what the client sent, one read a round (drain_input with a deadline
  // already past: a client that keeps sending does not hold the accept loop); false once it
  // has closed (or the read failed).
  static bool drain_round(int fd) { return drain_input(fd, Clock::now()) == IoStatus::timeout; }
  void close_at(size_t i) {
    ::close(open_[i].fd);
    open_.erase(open_.begin() + ptrdiff_t(i));
  }
  std::vector<Entry> open_;  // in order of their deadlines
};

}  // namespace

void SocketServer::accept_loop() {
  AnsweredConnections answered;
  std::vector<pollfd> fds;
  fds.reserve(2 + kMaxAnsweredOpen);
  for (;;) {
    fds.assign({{listen_fd_, POLLIN, 0}, {stop_pipe_[0], POLLIN, 0}});
    const int timeout_ms = answered.watch(fds);
    if (::poll(fds.data(), fds.size(), timeout_ms) < 0 && errno != EINTR) return;
    if (fds[1].revents) return;
    answered.service(fds.data() + 2);
    if (!(fds[0].revents & POLLIN)) continue;
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) continue;
    // Nothing a client brings may end the accept loop (it would end the service): a
    // connection that cannot be set up (no thread, no memory) is answered and closed.
    try {
      if (!accept_connection(fd)) answered.add(fd);
    } catch (const std::exception&) {
      ::close(fd);
    }
  }
}

bool SocketServer::accept_connection(int fd) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stopping_ || (open_slots() <= 0 && !evict_idle_connection())) {
    const json busy = error_response(
        "busy", stopping_ ? "the service is stopping"
                          : "too many clients (" + std::to_string(options_.max_clients) + "); try again later");
    write_message(fd, to_wire(busy), deadline_in(kBusyReplySeconds));
    return false;
  }
  connections_.emplace(fd, Connection{});
  ++clients_;
  try {
    std::thread([this, fd] { serve_connection(fd); }).detach();
  } catch (const std::exception&) {  // no thread could start (a thread or memory limit): this client only
    connections_.erase(fd);
    --clients_;
    const json busy = error_response("busy", "the service could not start a thread for this client; try again later");
    write_message(fd, to_wire(busy), deadline_in(kBusyReplySeconds));
    return false;
  }
  return true;
}

int SocketServer::open_slots() const {
  int taken = 0;
  for (const auto& [fd, connection] : connections_) taken += connection.evicted ? 0 : 1;
  return options_.max_clients - taken;
}

bool SocketServer::evict_idle_connection() {
  auto oldest = connections_.end();
  for (auto it = connections_.begin(); it != connections_.end(); ++it)
    if (!it->second.evicted && it->second.idle_since != Clock::time_point::max() &&
        (oldest == connections_.end() || it->second.idle_since < oldest->second.idle_since))
      oldest = it;
  if (oldest == connections_.end()) return false;
  oldest->second.evicted = true;
  write_message(oldest->first,
                to_wire(error_response("timeout", "idle connection closed: every slot (--max-clients " +
                                                      std::to_string(options_.max_clients) +
                                                      ") was taken and another client connected")),
                deadline_in(kBusyReplySeconds));
  ::shutdown(oldest->first, SHUT_RDWR);  // its thread sees the end and closes it
  return true;
}

bool SocketServer::set_idle(int fd, bool idle) {
  std::lock_guard<std::mutex> lock(mutex_);
  Connection& c = connections_[fd];
  c.idle_since = idle ? Clock::now() : Clock::time_point::max();
  return !c.evicted;
}

bool SocketServer::is_stopping() {
  std::lock_guard<std::mutex> lock(mutex_);
  return stopping_;
}

void SocketServer::set_replying(int fd, bool replying) {
  std::lock_guard<std::mutex> lock(mutex_);
  connections_[fd].replying_since = replying ? Clock::now() : Clock::time_point::max();
}

void SocketServer::cut_stalled_replies(Clock::time_point stop_time) {
  const auto grace = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kStopReplyGraceSeconds));
  const Clock::time_point now = Clock::now();
  for (auto& [fd, connection] : connections_) {
    if (connection.cut || connection.replying_since == Clock::time_point::max()) continue;
    if (now - std::max(stop_time, connection.replying_since) < grace) continue;
    connection.cut = true;
    ::shutdown(fd, SHUT_RDWR);  // its thread's write fails, and it closes the connection
  }
}

bool SocketServer::take(size_t& used, size_t limit, size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bytes > limit - std::min(used, limit)) return false;
  used += bytes;
  return true;
}

void SocketServer::give(size_t& used, size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  used -= std::min(used, bytes);
}

IoStatus SocketServer::read_header(int fd, std::string& header, bool& over_budget) {
  const Deadline deadline = deadline_in(options_.client_timeout_s);
  unsigned char prefix[4];
  if (const IoStatus s = read_exact(fd, prefix, 4, deadline); s != IoStatus::ok) return s;
  const uint32_t size = decode_length(prefix);
  if (size > options_.limits.max_header_bytes) return IoStatus::too_large;
  if (size > kSmallHeaderBytes) {
    over_budget = !take(header_bytes_, kHeaderBudgetRequests * options_.limits.max_header_bytes, size);
    if (over_budget) return IoStatus::error;
  }
  header.resize(size);
  const IoStatus s = read_exact(fd, header.data(), size, deadline);
  return s == IoStatus::closed ? IoStatus::truncated : s;
}

void SocketServer::serve_connection(int fd) {
  for (;;) {
    if (!set_idle(fd, true)) break;
    IoStatus s = wait_for_request(fd, deadline_in(options_.client_timeout_s));
    if (!set_idle(fd, false)) break;
    std::string header;
    bool over_budget = false;
    if (s == IoStatus::ok) s = read_header(fd, header, over_budget);
    if (over_budget) {
      reply(fd, error_response("busy", "the service holds as many request headers as it may (" +
                                           std::to_string(kHeaderBudgetRequests) +
                                           " x --max-request-bytes); try again later"));
      break;
    }
    if (s == IoStatus::timeout) {
      reply(fd, error_response("timeout", "no complete request within " +
                                              number_text(options_.client_timeout_s) + " s (--client-timeout)"));
    } else if (s == IoStatus::truncated) {  // a client that stopped sending may still read
      reply(fd, error_response("bad_request", "the request header was cut short (the connection's sending side "
                                              "closed in the middle of it)"));
    } else if (s == IoStatus::too_large) {
      reply(fd, error_response("too_large", "the request header exceeds " +
                                                std::to_string(options_.limits.max_header_bytes) +
                                                " bytes (--max-request-bytes)"));
    }
    // The header's bytes stay taken while its request is served (its parsed form lives as long).
    const bool go_on = s == IoStatus::ok && handle_request(fd, header);
    if (header.size() > kSmallHeaderBytes) give(header_bytes_, header.size());
    if (!go_on) break;
  }
  // The client may still be sending (a header over --max-request-bytes, inline bytes its
  // request was refused before): the connection ends once it has stopped, or after
  // kAnsweredOpenSeconds, so that its sending does not fail before it reads the answer.
  ::shutdown(fd, SHUT_WR);
  drain_input(fd, deadline_in(kAnsweredOpenSeconds));
  std::lock_guard<std::mutex> lock(mutex_);
  connections_.erase(fd);
  ::close(fd);
  --clients_;
  all_closed_.notify_all();
  // The thread is detached; stop() waits on all_closed_ for the set to empty.
}

bool SocketServer::reply(int fd, const json& response, const std::string& inline_file) {
  set_replying(fd, true);
  const bool sent = send_reply(fd, response, inline_file);
  set_replying(fd, false);
  return sent;
}

bool SocketServer::send_reply(int fd, const json& response, const std::string& inline_file) {
  const Deadline deadline = deadline_in(options_.client_timeout_s);
  if (inline_file.empty()) return write_message(fd, to_wire(response), deadline) == IoStatus::ok;
  const int in = ::open(inline_file.c_str(), O_RDONLY | O_CLOEXEC);
  struct stat st {};
  if (in < 0 || ::fstat(in, &st) != 0) {
    if (in >= 0) ::close(in);
    return write_message(fd,
                         to_wire(error_response("internal", "the output vanished before it was sent",
                                                response.value("id", json()))),
                         deadline) == IoStatus::ok;
  }
  json header = response;
  header["inline_size"] = uint64_t(st.st_size);
  bool ok = write_message(fd, to_wire(header), deadline) == IoStatus::ok;
  std::vector<char> buffer(size_t(1) << 20);
  for (off_t left = st.st_size; ok && left > 0;) {
    const ssize_t n = ::read(in, buffer.data(), size_t(std::min<off_t>(left, off_t(buffer.size()))));
    if (n <= 0) {
      ok = false;  // the peer sees a truncated message: better than a wrong one
      break;
    }
    ok = write_all(fd, buffer.data(), size_t(n), deadline) == IoStatus::ok;
    left -= n;
  }
  ::close(in);
  return ok;
}

bool SocketServer::handle_request(int fd, const std::string& header) {
  SocketRequest request;
  std::string error;
  if (!parse_socket_request(header, options_.limits, request, error)) {
    // The stream may hold a payload of unknown size: answer and close. The id, when the
    // header got far enough to have one, is in `request` (never re-parsed here: the header
    // may be nested too deeply to copy).
    reply(fd, error_response("bad_request", error, request.id));
    return false;
  }
  if (request.op == "ping") {
    json pong{{"ok", true}, {"op", "ping"}, {"version", version_string()}, {"protocol", kProtocolVersion}};
    if (!request.id.is_null()) pong["id"] = request.id;
    return reply(fd, pong);
  }
  if (request.op == "stats") {
    json stats = stats_json(frames_.stats(), clients_);
    if (options_.watch_status) stats["watch"] = options_.watch_status();
    if (!request.id.is_null()) stats["id"] = request.id;
    return reply(fd, stats);
  }
  return handle_process(fd, request);
}

bool SocketServer::handle_process(int fd, SocketRequest& request) {
  const json& id = request.id;
  // Refuses the request; a pending inline payload makes the connection close.
  auto refuse = [&](const std::string& code, const std::string& message) {
    reply(fd, error_response(code, message, id));
    return request.inline_size == 0;
  };
  FrameOptionArgs options;
  std::string error;
  if (!apply_json(options_.default_options, options, error) || !apply_json(request.options, options, error))
    return refuse("bad_request", "options: " + error);
  for (std::string* path : {&options.read.camera_json, &options.compute.env_path}) {
    if (path->empty()) continue;
    std::string resolved;
    if (!resolve_allowed_input(*path, options_.allow_roots, resolved, error)) return refuse("forbidden", error);
    std::error_code ec;
    if (!fs::is_regular_file(resolved, ec)) return refuse("bad_request", *path + ": not a regular file");
    *path = resolved;
  }
  // Every option resolved as the worker will (the environment by its header only): a
  // value no frame could be computed with is the request's error, answered now, before a
  // worker fails the frame and its error file replaces the frame's good output.
  if (FrameRequest checked; !resolve_frame_options(options, checked, error, /*build_environment=*/false))
    return refuse("bad_request", "options: " + error);

  // Where the frame comes from and where its output goes.
  const bool inline_input = request.inline_size > 0;
  const unsigned long spool_id = ++next_spool_id_;
  const fs::path spool = fs::path(options_.spool_dir) / ("r" + std::to_string(spool_id));
  struct SpoolGuard {
    fs::path dir;
    bool used = false;
    ~SpoolGuard() {
      std::error_code ec;
      if (used) fs::remove_all(dir, ec);
    }
  } guard{spool};
  // The inline frame's bytes are taken out of the spool budget until the request is done.
  struct SpoolBytes {
    SocketServer& server;
    size_t bytes = 0;
    ~SpoolBytes() { server.give(server.spool_bytes_, bytes); }
  } spool_bytes{*this};
  std::string input;
  if (request.inline_size > 0) {
    if (request.inline_size > options_.max_spool_bytes)  // never fits, however long the client waits
      return refuse("bad_request", "an inline frame of " + std::to_string(request.inline_size) +
                                       " bytes is larger than the whole spool (--max-spool-mb " +
                                       std::to_string(options_.max_spool_bytes >> 20) + ")");
    if (!take(spool_bytes_, options_.max_spool_bytes, request.inline_size))
      return refuse("busy", "the spool holds as many inline frames as it may (" +
                                std::to_string(options_.max_spool_bytes >> 20) +
                                " MiB, --max-spool-mb); try again later");
    spool_bytes.bytes = request.inline_size;
    std::error_code ec;
    make_spool_folder(spool, ec);
    guard.used = true;
    if (ec) return refuse("internal", "cannot create a spool folder: " + ec.message());
    input = (spool / (request.name + ".exr")).string();
    if (!stream_to_file(fd, input, request.inline_size, deadline_in(options_.client_timeout_s), error)) {
      // A stop shuts the connections' reading side: the client did not cut its upload short.
      if (is_stopping())
        reply(fd, error_response("busy", "the service is stopping: the inline frame was not received whole", id));
      else reply(fd, error_response("bad_request", error, id));
      return false;
    }
    request.inline_size = 0;  // consumed: the stream is in step again
    if (request.sidecar.is_object()) {
      FILE* f = std::fopen((spool / (request.name + ".camera.json")).c_str(), "w");
      if (!f) return refuse("internal", "cannot write the sidecar to the spool folder");
      const std::string text = to_wire(request.sidecar);
      std::fwrite(text.data(), 1, text.size(), f);
      std::fclose(f);
    }
  } else {
    if (!resolve_allowed_input(request.input, options_.allow_roots, input, error)) return refuse("forbidden", error);
    std::error_code ec;
    if (!fs::is_regular_file(input, ec)) return refuse("bad_request", request.input + ": not a regular file");
  }
  std::vector<std::string> views;
  for (const std::string& view : request.views) {
    std::string resolved;
    if (!resolve_allowed_input(view, options_.allow_roots, resolved, error)) return refuse("forbidden", error);
    views.push_back(resolved);
  }
  std::string output, error_path;
  if (request.reply_inline) {
    std::error_code ec;
    make_spool_folder(spool, ec);
    guard.used = true;
    output = (spool / (fs::path(input).stem().string() + ".ssdo.exr")).string();
  } else if (!request.output.empty()) {
    // A relative output is under --out (the service's working folder means nothing to a client).
    const fs::path wanted = fs::path(request.output).is_relative() ? fs::path(options_.out_dir) / request.output
                                                                    : fs::path(request.output);
    if (!resolve_allowed_output(wanted.string(), options_.out_dir, output, error)) return refuse("forbidden", error);
    if (path_is_under(output, options_.spool_dir))
      return refuse("forbidden", request.output + ": inside the service's private spool folder");
    // Not the service's own files (its lock, spool and temp files start with '.') nor error
    // files or frames' sidecars: an output is an EXR.
    if (const std::string name = fs::path(output).filename().string(); name[0] == '.' || !has_exr_extension(name))
      return refuse("bad_request", request.output + ": an output is an .exr file name, and not a hidden one");
    // The watch takes every EXR of its folder but outputs (NAME.ssdo.exr) for a frame: an
    // output of another name there would be computed as a frame in turn (and fail, leaving
    // an error file), claim NAME.ssdo.exr, and join the neighbours of its sequence's frames.
    if (!options_.watch_dir.empty() && fs::path(output).parent_path() == options_.watch_dir && is_frame_file(output))
      return refuse("bad_request", request.output + ": in the watched folder an output is named NAME.ssdo.exr (" +
                                       fs::path(output).stem().string() +
                                       ".ssdo.exr); the watch takes any other .exr there for a frame");
    // Never over a frame: the input, one of its views, or any file that is not an output of
    // ssdo (a watched frame in the output folder, another program's file); a failure would
    // remove it too.
    if (std::error_code ec; fs::exists(output, ec)) {
      for (const std::string& frame : views)
        if (fs::equivalent(output, frame, ec))
          return refuse("bad_request",
                        request.output + ": is one of the frame's views; an output never replaces a frame");
      if (fs::equivalent(output, input, ec))
        return refuse("bad_request", request.output + ": is the input frame; an output never replaces a frame");
      if (!read_string_attribute(output, kVersionAttribute))
        return refuse("conflict", request.output + ": exists and is not an output of ssdo; it is not replaced");
    }
    error_path = error_path_for_output(output);
  } else {
    output = output_path_for(input, options_.out_dir);
    error_path = error_path_for(input, options_.out_dir);
  }
  // Refused rather than renamed: a client finds its result where it expects it, or is told.
  if (std::string owner; !request.reply_inline &&
                         !frames_.claim_output(output, inline_input ? "inline upload " + request.name : input, owner))
    return refuse("conflict", output + " is already the output of " + owner + "; give this frame another \"output\"");
  if (!request.reply_inline && !frames_.begin_output(output))
    return refuse("conflict", output + " is being computed for another request now; try again when it is done, or give "
                              "this frame another " + std::string(inline_input ? "\"name\"" : "\"output\""));

  // Queue it and wait for the result (a dispatcher always calls back: with the frame's
  // result, or "stopping" for a queued frame when the service stops).
  struct Outcome {
    std::mutex mutex;
    std::condition_variable cv;
    bool done = false;
    WorkerResult result;
  };
  auto outcome = std::make_shared<Outcome>();
  FrameTask task;
  task.input = input;
  task.output = output;
  task.error_path = error_path;
  if (inline_input) task.inline_name = request.name;
  task.options = to_json(options);
  task.neighbours = named_neighbours(input, views);
  // The worker opens every file again itself, confined the same way (service/job_files.h):
  // the checks above give early, precise refusals; the worker's opens are the ones that hold.
  task.confine.input_roots = inline_input ? std::vector<std::string>{spool.string()} : options_.allow_roots;
  task.confine.option_roots = options_.allow_roots;
  task.confine.view_roots = options_.allow_roots;  // named views: checked against --allow above
  task.confine.output_root = request.reply_inline ? spool.string() : options_.out_dir;
  auto abandoned = std::make_shared<std::atomic<bool>>(false);
  task.abandoned = abandoned;
  // The output stays in flight until its frame is done, also for a client that left.
  const bool in_flight = !request.reply_inline;
  task.done = [outcome, in_flight, output, frames = &frames_](const WorkerResult& r) {
    if (in_flight) frames->end_output(output);
    std::lock_guard<std::mutex> lock(outcome->mutex);
    outcome->result = r;
    outcome->done = true;
    outcome->cv.notify_all();
  };
  const auto t0 = Clock::now();
  if (!frames_.submit(std::move(task))) {
    if (in_flight) frames_.end_output(output);
    if (is_stopping()) return refuse("busy", "the service is stopping");
    const ServiceStats s = frames_.stats();
    return refuse("busy", "the queue is full (" + std::to_string(s.queue_capacity) + " frames); try again later");
  }
  // While it waits, the connection watches its client: one that has closed (not merely
  // shut its sending side: POLLHUP, not POLLRDHUP) gives its slot back at once, and its
  // frame is dropped from the queue or not tried again (a frame in flight finishes).
  std::unique_lock<std::mutex> lock(outcome->mutex);
  while (!outcome->cv.wait_for(lock, std::chrono::milliseconds(kPeerCheckMs), [&] { return outcome->done; })) {
    if (peer_closed(fd)) {
      abandoned->store(true);
      lock.unlock();  // a task dropped now is answered through `outcome`
      frames_.drop_abandoned();
      return false;
    }
  }
  const WorkerResult r = outcome->result;
  lock.unlock();

  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  json times{{"read_ms", r.times.read_ms},
             {"compute_ms", r.times.compute_ms},
             {"write_ms", r.times.write_ms},
             {"worker_ms", r.wall_ms},
             {"total_ms", total_ms}};
  if (!r.ok()) {
    json response = error_response("frame_failed", r.error, id);
    response["times"] = times;
    // Named only when written: a frame dropped from the queue at a stop has none.
    if (std::error_code ec; !error_path.empty() && fs::exists(error_path, ec)) response["error_file"] = error_path;
    return reply(fd, response);
  }
  json response{{"ok", true},          {"terms", r.terms}, {"width", r.width_px},
                {"height", r.height_px}, {"times", times},   {"notes", r.notes}};
  // The shot's window the frame was computed with; "note" says why when it is smaller than asked.
  response["window"] = {{"views", r.views_per_side},
                        {"temporal", r.temporal_per_side},
                        {"reduced", r.window_reduced()}};
  if (r.window_reduced()) response["window"]["note"] = r.window_note;
  if (!r.warnings.empty()) response["warnings"] = r.warnings;  // the input changed while computed
  if (!id.is_null()) response["id"] = id;
  if (request.reply_inline) return reply(fd, response, output);
  response["output"] = output;
  return reply(fd, response);
}

void make_private_folder(const fs::path& folder, std::error_code& ec) {
  fs::create_directory(folder, ec);
  fs::permissions(folder, fs::perms::owner_all, ec);
}

}  // namespace ssdo
