#pragma once
/// @file
/// The local web server of `chronomap view`: serves one 4D map's Api (api.h) over HTTP with
/// cpp-httplib, and nothing of the disk.

#include <memory>
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
  ApiSettings api;
};

/// An HTTP server of one map. The map must outlive it.
class Server {
 public:
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
