#pragma once
// The viewer's connections, guarded against slow clients. cpp-httplib reads a request on one of
// its pool's threads and waits up to its read timeout for each piece, so a client that sends its
// header a byte at a time holds a thread for as long as it likes: 8 such clients held the whole
// pool and every other request waited behind them. Here a connection gets a thread only once its
// request header has arrived whole; until then (and between the requests of a kept-alive
// connection) it waits in one poll loop, the lobby, for a limited time, and a limited number
// wait at once.

// After Eigen: httplib.h includes <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

#include <chrono>
#include <cstddef>
#include <string>

namespace chronomap {

/// How long and how many connections the server holds.
struct ConnectionLimits {
  /// From a connection's acceptance to the end of its request (header and body).
  std::chrono::milliseconds request_timeout{5000};
  /// From an answer to the end of the next request on the same connection.
  std::chrono::milliseconds keep_alive_timeout{5000};
  /// The longest wait for a client to take more of an answer.
  std::chrono::milliseconds write_timeout{5000};
  /// The longest time one answer may take to send.
  std::chrono::milliseconds answer_timeout{60000};
  /// Threads that answer complete requests.
  size_t threads = 8;
  /// Connections waiting in the lobby at once; a new one closes the one that waited longest.
  size_t max_waiting = 64;
  /// Connections the kernel queues before the accept loop takes them (cpp-httplib's 5 made a
  /// burst of connections wait a second each for the client to try again).
  int listen_backlog = 128;
};

/// cpp-httplib's server with its connections handled as above: every request it answers (its
/// routes, handlers and pre-routing handler are the base class's) has arrived whole.
class GuardedHttpServer : public httplib::Server {
 public:
  explicit GuardedHttpServer(ConnectionLimits limits);
  /// After binding: lets the kernel queue listen_backlog connections.
  void widenBacklog();

 private:
  class Lobby;
  struct Waiting;
  // Called by cpp-httplib's accept loop for each new connection: hands it to the lobby.
  bool process_and_close_socket(socket_t sock) override;
  // On a lobby thread: answers the request that has arrived on `w`; then the connection goes
  // back to the lobby or is closed.
  void answer(Lobby& lobby, Waiting w);

  ConnectionLimits limits_;
  // The lobby of the running listen() (cpp-httplib owns it as its task queue), else null.
  Lobby* lobby_ = nullptr;
};

}  // namespace chronomap
