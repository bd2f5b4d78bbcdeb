// The service socket of `ssdo serve --socket PATH`: a Unix domain stream socket speaking
// length-prefixed JSON (service/protocol.h; docs/service.md, "Wire protocol").
// - One thread per connection, at most `max_clients` at once (beyond: "busy" and close);
//   every read and write has a deadline (`client_timeout_s`), so a slow or silent client
//   holds only its own thread, and only for that long.
// - Paths are resolved (realpath) and must lie under an --allow root (inputs, camera and
//   environment files) or under --out (outputs); inline frames are streamed into a spool
//   folder, never held in memory, and given to a worker by path.
// - A full queue answers "busy"; nothing waits in memory beyond the queue's capacity.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <set>
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
  ProtocolLimits limits;
  double client_timeout_s = 30;         // to receive a whole request, and to send a reply
  double frame_timeout_s = 300;         // the workers' limit; replies wait at most this + margin
  int max_clients = 64;                 // connections served at once
  nlohmann::json default_options = nlohmann::json::object();  // the service's frame options
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
  // Stops accepting and removes the socket file; open connections go on.
  void stop_accepting();
  // Stops accepting and removes the socket file; connections finish the request they are
  // in (its frame included) and close. Idempotent.
  void stop();
  int clients() const { return clients_; }

 private:
  void accept_loop();
  void serve_connection(int fd);
  // Handles one request; false when the connection must close (the stream is out of step).
  bool handle_request(int fd, const std::string& header);
  bool handle_process(int fd, SocketRequest& request);
  bool reply(int fd, const nlohmann::json& response, const std::string& inline_file = {});

  const SocketServerOptions options_;
  FrameService& frames_;
  int listen_fd_ = -1;
  int stop_pipe_[2] = {-1, -1};
  std::thread accept_thread_;
  std::atomic<int> clients_{0};
  std::atomic<unsigned long> next_spool_id_{0};
  std::mutex mutex_;
  std::condition_variable all_closed_;
  std::set<int> connections_;
  bool stopping_ = false;
};

}  // namespace ssdo
