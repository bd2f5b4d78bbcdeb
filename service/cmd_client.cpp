// `ssdo client`: speaks the service's socket protocol (docs/service.md, "Wire protocol"), for
// shell pipelines and tests. Prints one JSON response per line; exit 0 when every
// request succeeded, 1 when any failed, 2 when the service cannot be reached.
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>

#include <CLI/CLI.hpp>

#include "formats/input_file.h"
#include "formats/output_writer.h"
#include "service/cli_options.h"
#include "service/commands.h"
#include "service/frame_list.h"
#include "service/frame_options.h"

namespace ssdo {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

int connect_to(const std::string& path, std::string& error) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof addr.sun_path) {
    error = path + ": socket path too long";
    return -1;
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    error = path + ": cannot connect: " + std::strerror(errno);
    if (fd >= 0) ::close(fd);
    return -1;
  }
  return fd;
}

// The bytes of a file to send inline; empty with a message naming it when it is not a
// regular file or cannot be read (nothing is sent then).
std::string read_payload(const std::string& path, std::string& error) {
  if (error = input_file_error(path, ""); !error.empty()) return {};
  std::ifstream in(path, std::ios::binary);
  std::string bytes(std::istreambuf_iterator<char>(in), {});
  if (!in.good() && !in.eof()) error = path + ": cannot read";
  else if (bytes.empty()) error = path + ": an empty file";
  return error.empty() ? bytes : std::string();
}

// Sends `request` (+ `payload`, its inline bytes) and reads the response (+ its inline
// bytes into `inline_out`). False with a message on a transport failure.
bool exchange(int fd, json request, const std::string& payload, json& response, std::string& inline_out,
              size_t max_inline_mb, Deadline deadline, std::string& error) {
  if (!payload.empty()) request["inline_size"] = payload.size();
  IoStatus s = write_message(fd, to_wire(request), deadline);
  if (s == IoStatus::ok && !payload.empty()) s = write_all(fd, payload.data(), payload.size(), deadline);
  std::string header;
  // Read the reply even when sending failed: the service may have refused early.
  const IoStatus r = read_message(fd, header, size_t(1) << 20, deadline);
  if (r != IoStatus::ok) {
    error = std::string("no response: ") + to_string(r != IoStatus::ok ? r : s);
    return false;
  }
  response = json::parse(header, nullptr, false);
  if (response.is_discarded() || !response.is_object()) {
    error = "malformed response";
    return false;
  }
  const json& size = response.contains("inline_size") ? response["inline_size"] : json(0);
  if (!size.is_number_unsigned() && !(size.is_number_integer() && size.get<int64_t>() >= 0)) {
    error = "malformed response: inline_size is not a byte count";
    return false;
  }
  if (const auto n = size.get<uint64_t>(); n > 0) {
    // The reply is held in memory before it is written: a size beyond the limit is refused,
    // whatever the service announces.
    if (n > uint64_t(max_inline_mb) << 20) {
      error = "the service announced an inline reply of " + std::to_string(n) + " bytes, over the limit of " +
              std::to_string(max_inline_mb) + " MiB (--max-inline-mb)";
      return false;
    }
    inline_out.resize(n);
    if (read_exact(fd, inline_out.data(), n, deadline) != IoStatus::ok) {
      error = "the output's bytes were cut short";
      return false;
    }
  }
  return true;
}

// The options as the service must read them: a file an option names (--camera, --env) is
// the one the client's working directory gives, so its path goes absolute (the service
// resolves relative paths against its own). With --inline the service reads no file of
// the client's: a --camera file goes as the request's sidecar instead.
bool options_for_service(const ClientArgs& args, json& options, json& sidecar, std::string& error) {
  options = args.options;
  for (const FrameOption& o : frame_options()) {
    if (!o.file || !options.contains(o.name) || !options[o.name].is_string()) continue;
    const std::string path = options[o.name].get<std::string>();
    if (path.empty()) continue;
    if (args.inline_data && std::string(o.name) == "camera") {
      std::ifstream in(path);
      sidecar = json::parse(in, nullptr, false);
      if (!in || !sidecar.is_object()) {
        error = path + ": --camera: not a JSON object (read as the requests' sidecar with --inline)";
        return false;
      }
      options.erase(o.name);
      continue;
    }
    options[o.name] = fs::absolute(path).string();
  }
  return true;
}

}  // namespace

int run_client(const ClientArgs& args) {
  if (args.action != "process" && !args.files.empty()) {
    std::cerr << "ssdo client: " << args.action << " takes no files\n";
    return 2;
  }
  if (args.action != "process" && !args.options.empty()) {
    std::cerr << "ssdo client: " << args.action << " takes no frame options (" << args.options.begin().key()
              << " given): they are a process request's\n";
    return 2;
  }
  if (args.action == "process" && args.files.empty()) {
    std::cerr << "ssdo client: process needs at least one FILE\n";
    return 2;
  }
  std::string error;
  int fd = connect_to(args.socket_path, error);
  if (fd < 0) {
    std::cerr << "ssdo client: " << error << "\n";
    return 2;
  }
  json options, camera_sidecar;
  if (!options_for_service(args, options, camera_sidecar, error)) {
    std::cerr << "ssdo client: " << error << "\n";
    ::close(fd);
    return 2;
  }
  int failed = 0;
  std::vector<json> requests;
  std::vector<std::string> payloads;
  if (args.action != "process") {
    requests.push_back({{"op", args.action}});
    payloads.emplace_back();
  }
  for (const std::string& file : args.files) {
    json r{{"op", "process"}, {"options", options}};
    if (args.inline_data) {
      const fs::path p(file);
      r["name"] = safe_name_for(p.stem().string());  // the spool's name for it: a plain stem
      r["reply"] = "inline";
      const fs::path sidecar = p.parent_path() / (p.stem().string() + ".camera.json");
      std::ifstream in(sidecar);
      if (!camera_sidecar.is_null()) {
        r["sidecar"] = camera_sidecar;
      } else if (in) {
        const json s = json::parse(in, nullptr, false);
        if (s.is_object()) r["sidecar"] = s;
      }
      payloads.push_back(file);
    } else {
      r["input"] = fs::absolute(file).string();
      payloads.emplace_back();
    }
    requests.push_back(r);
  }
  if (args.inline_data) {
    // Outputs are named after the files: two files of one name would write one output.
    std::map<std::string, std::string> file_of_output;
    for (const std::string& file : args.files)
      if (const auto [it, fresh] = file_of_output.emplace(output_path_for(file, args.out_dir), file);
          !fresh && it->second != file) {
        std::cerr << "ssdo client: " << it->second << " and " << file << " would both be written to " << it->first
                  << " (the same file name): send them with different -o folders\n";
        ::close(fd);
        return 2;
      }
    std::error_code ec;
    fs::create_directories(args.out_dir, ec);
    if (ec || !fs::is_directory(args.out_dir, ec)) {
      std::cerr << "ssdo client: -o " << args.out_dir << ": cannot create the folder"
                << (ec ? ": " + ec.message() : std::string(" (a file of that name is in the way)")) << "\n";
      ::close(fd);
      return 2;
    }
  }
  for (size_t i = 0; i < requests.size(); ++i) {
    json response;
    std::string bytes, payload;
    if (!payloads[i].empty()) {
      // A file that cannot be read is that file's failure, with its own line; nothing was
      // sent, and the next file goes over the same connection.
      if (payload = read_payload(payloads[i], error); !error.empty()) {
        ++failed;
        std::cout << to_wire(json{{"ok", false}, {"input", args.files[i]}, {"error", error}}) << "\n" << std::flush;
        continue;
      }
    }
    if (fd < 0 || !exchange(fd, requests[i], payload, response, bytes, args.max_inline_mb,
                            deadline_in(args.timeout_s), error)) {
      // The files not sent are named, each: a batch's log shows every frame's fate.
      std::cerr << "ssdo client: " << (i < args.files.size() ? args.files[i] + ": " : "") << error << "\n";
      for (size_t k = i + 1; k < args.files.size(); ++k)
        std::cerr << "ssdo client: " << args.files[k] << ": not sent (the connection failed)\n";
      if (fd >= 0) ::close(fd);
      return 2;
    }
    if (!bytes.empty()) {
      const std::string out = output_path_for(args.files[i], args.out_dir);
      if (const std::string written = write_file_atomically(out, bytes); !written.empty()) {
        response["ok"] = false;
        response["error"] = written;
      } else {
        response["output"] = out;
      }
      response.erase("inline_size");
    }
    if (!response.value("ok", false)) ++failed;
    std::cout << to_wire(response) << "\n" << std::flush;
    // A refused request may leave the stream out of step (inline bytes the service did not
    // read), and the service then closes it (bad_request, forbidden, ...): after any refusal
    // the next file goes over a new connection.
    if (!response.value("ok", false) && i + 1 < requests.size()) {
      ::close(fd);
      fd = connect_to(args.socket_path, error);
    }
  }
  if (fd >= 0) ::close(fd);
  return failed > 0 ? 1 : 0;
}

Command register_client(CLI::App& app) {
  auto st = std::make_shared<CommandState<ClientArgs>>();
  ClientArgs& c = st->args;
  CLI::App* cmd = app.add_subcommand(
      "client", "Talk to a running 'ssdo serve --socket': ping, stats, or process FILE... (one JSON "
                "response per line)");
  cmd->add_option("--socket", c.socket_path, "The service's socket")->required();
  cmd->add_option("action", c.action, "ping, stats or process")
      ->required()
      ->check(CLI::IsMember({"ping", "stats", "process"}));
  cmd->add_option("files", c.files, "process: frames (paths the service may read, or sent with --inline)");
  cmd->add_flag("--inline", c.inline_data,
                "Send the frames' bytes (and NAME.camera.json) and receive the outputs' bytes");
  cmd->add_option("-o,--out", c.out_dir, "--inline: folder for the outputs")->capture_default_str();
  cmd->add_option("--max-inline-mb", c.max_inline_mb, "--inline: largest output the service may send back, MiB")
      ->check(CLI::Range(size_t(1), size_t(1) << 20))
      ->capture_default_str();
  cmd->add_option("--timeout", c.timeout_s, "Seconds to wait for each response")
      ->check(seconds_in(0.001, 604800.0))
      ->capture_default_str();
  add_frame_options(*cmd, st->options);
  return {cmd, [st, cmd] {
            // Only the flags given: the service's own options fill the rest.
            st->args.options = to_json(st->options, [&](const std::string& key) { return given(*cmd, key); });
            return run_client(st->args);
          }};
}

}  // namespace ssdo
