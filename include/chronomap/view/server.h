#pragma once
/// @file
/// The local web server of `chronomap view`: serves one 4D map's Api (api.h) over HTTP with
/// cpp-httplib, and nothing of the disk. It answers only requests addressed to a loopback name
/// or the address it serves on (hostRefusal), and slow clients cannot hold the others out (a
/// connection gets a thread only once its request has arrived whole, within request_timeout_s).

#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include "chronomap/temporal/temporal_map.h"
#include "chronomap/view/api.h"

namespace chronomap {

/// Where and how the server listens.
struct ServerSettings {
  /// The address to bind: the loopback interface unless another is asked for explicitly.
  std::string host = "127.0.0.1";
  /// The port; 0 picks a free one.
  int port = 8765;
  /// Seconds a client has, from connecting, to send its request (header and body); one that
  /// takes longer is disconnected.
  double request_timeout_s = 5.0;
  /// Seconds an idle kept-alive connection is held open for its next request.
  double keep_alive_timeout_s = 5.0;
  /// Seconds the server waits for a client to take more of an answer before disconnecting it.
  double write_timeout_s = 5.0;
  /// Threads that answer requests, each one whole request at a time.
  int threads = 8;
  /// Connections held open while they send a request or wait for their next one; one more
  /// closes the one held longest.
  size_t max_open_connections = 64;
  ApiSettings api;
};

/// Whether `host` (an address or name to listen on) is this machine's loopback interface:
/// localhost, 127.0.0.0/8 or ::1 (with or without brackets).
bool isLoopbackHost(const std::string& host);

/// Why a server listening on `served_host` refuses a request whose Host header is `host_header`,
/// or nothing when it answers it. Answered: localhost, 127.0.0.0/8 and [::1], the served address
/// itself (a name case-insensitively, an address in any spelling), and when it serves on every
/// interface (0.0.0.0, ::) any address literal; each with or without a port, any port (an SSH
/// tunnel forwards another). Refused: every other name, which a web page of another site can
/// point at this machine to read the map (DNS rebinding), and malformed values.
std::optional<std::string> hostRefusal(const std::string& host_header, const std::string& served_host);

/// The warning that serving on `host` (port `port`) lets other machines read the map, or
/// nothing for a loopback address.
std::optional<std::string> exposureWarning(const std::string& host, int port);

/// An HTTP server of one map. The map must outlive it.
class Server {
 public:
  /// @throw UsageError when a timeout, the threads or the open connections are not positive.
  Server(const TemporalMap& map, std::string name, ServerSettings settings = {});
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Binds the address. @return the port bound. @throw IoError when it cannot be bound.
  int bind();
  /// Answers requests until stop() (call bind() first). @throw IoError when listening fails.
  void serve();
  /// Makes serve() return; safe from another thread or a signal-handling thread.
  void stop();
  /// "http://HOST:PORT/" once bound.
  std::string url() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace chronomap
