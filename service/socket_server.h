// The service socket of `ssdo serve --socket PATH`: a Unix domain stream socket speaking
// length-prefixed JSON (service/protocol.h; docs/service.md, "Wire protocol").
// - One thread per connection, at most `max_clients` at once; every read and write has a
//   deadline (`client_timeout_s`), so a slow or silent client holds only its own thread,
//   and only for that long. When every slot is taken, a new client takes the slot of the
//   connection idle the longest (connected, or done with its last request, and no byte
//   of a new one yet), which is closed; with no idle connection the new one is answered
//   "busy" and closed.
// - Memory and disk shared by all connections are bounded: request headers over 4 KiB being
//   read or served hold at most 16 x max_header_bytes together, inline frames
//   in the spool at most `max_spool_bytes`; a request beyond either is answered "busy".
// - Paths are resolved (realpath) and must lie under an --allow root (inputs, camera and
//   environment files) or under --out (outputs); inline frames are streamed into a spool
//   folder, never held in memory, and given to a worker by path.
// - A full queue answers "busy"; nothing waits in memory beyond the queue's capacity.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <mutex>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/frame_service.h"
#include "service/protocol.h"

namespace ssdo {

struct SocketServerOptions {
  std::string path;                     // socket file
  mode_t mode = 0600;                   // its permissions
  std::vector<std::string> allow_roots; // canonical folders inputs may come from
  std::string out_dir;                  // canonical output folder
  std::string spool_dir;                // canonical folder for inline frames (private)
  std::string watch_dir;                // canonical watched folder; empty = none
  ProtocolLimits limits;
  double client_timeout_s = 30;         // to receive a whole request, and to send a reply
  double frame_timeout_s = 300;         // the workers' limit; replies wait at most this + margin
  int max_clients = 64;                 // connections served at once
  size_t max_spool_bytes = size_t(2048) << 20;  // inline frames in the spool, all requests together
  nlohmann::json default_options = nlohmann::json::object();  // the service's frame options
  std::function<nlohmann::json()> watch_status;  // "watch" of the stats reply; empty = none
};

class SocketServer {
 public:
  SocketServer(SocketServerOptions options, FrameService& frames);
  ~SocketServer();  // stop()

  // Creates the socket (mode `mode`; a stale socket file with no listener is replaced,
  // anything else at `path` is an error) and listens. Call before starting other threads
  // (the socket is created under a temporary umask).
  bool bind(std::string& error);
  // Starts accepting.
  void start();
  // Stops accepting and removes the socket file (when it is still the one bound here);
  // open connections go on.
  void stop_accepting();
  // Stops accepting and removes the socket file; connections finish the request they are
  // in (its frame included) and close. A reply not taken within kStopReplyGraceSeconds of
  // the stop (or of its start, when later) is cut off: a client that never reads holds
  // the exit back that long, not its whole --client-timeout. Idempotent.
  void stop();
  int clients() const { return clients_; }

 private:
  void accept_loop();
  // Registers an accepted client and starts its thread (true), or answers it busy (false:
  // the loop closes it once its client has sent); throws only when even that fails (the
  // loop then closes it at once).
  bool accept_connection(int fd);
  void serve_connection(int fd);
  // Handles one request; false when the connection must close (the stream is out of step).
  bool handle_request(int fd, const std::string& header);
  bool handle_process(int fd, SocketRequest& request);
  // Sends a reply (the response, then the inline file's bytes when one is named), marked
  // as replying while it is sent (set_replying); false when it could not be sent whole.
  bool reply(int fd, const nlohmann::json& response, const std::string& inline_file = {});
  bool send_reply(int fd, const nlohmann::json& response, const std::string& inline_file);
  void unlink_own_socket();
  // Reads one request header within the header budget; `over_budget` when it does not fit.
  IoStatus read_header(int fd, std::string& header, bool& over_budget);
  // Takes `bytes` of a shared budget (`used` out of `limit`) or refuses; give back after.
  bool take(size_t& used, size_t limit, size_t bytes);
  void give(size_t& used, size_t bytes);
  // Marks a connection idle (waiting for a request) or busy; false when it was evicted.
  bool set_idle(int fd, bool idle);
  bool is_stopping();
  // Marks a connection as sending a reply, or done with it.
  void set_replying(int fd, bool replying);
  // While stopping: shuts down the connections whose reply has waited longer than the
  // grace since `stop_time` or since it started (their writes then fail at once).
  void cut_stalled_replies(Clock::time_point stop_time);  // under mutex_
  int open_slots() const;  // under mutex_
  // With every slot taken: closes the connection idle the longest. False when none is idle.
  bool evict_idle_connection();  // under mutex_

  const SocketServerOptions options_;
  FrameService& frames_;
  int listen_fd_ = -1;
  dev_t socket_dev_ = 0;  // the socket file bind() created
  ino_t socket_ino_ = 0;
  int stop_pipe_[2] = {-1, -1};
  std::thread accept_thread_;
  std::atomic<int> clients_{0};
  std::atomic<unsigned long> next_spool_id_{0};
  std::mutex mutex_;
  std::condition_variable all_closed_;
  struct Connection {
    Clock::time_point idle_since = Clock::time_point::max();  // max: inside a request
    bool evicted = false;  // its slot was given to a new client; it is closing
    Clock::time_point replying_since = Clock::time_point::max();  // max: not sending a reply
    bool cut = false;  // shut down by stop() (cut_stalled_replies)
  };
  std::map<int, Connection> connections_;
  size_t header_bytes_ = 0, spool_bytes_ = 0;  // taken out of the shared budgets
  bool stopping_ = false;
};

// Creates `folder` (its parent must exist) readable and writable by the service's user
// alone (mode 0700): the spool of inline frames.
void make_private_folder(const std::filesystem::path& folder, std::error_code& ec);

}  // namespace ssdo
