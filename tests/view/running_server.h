#pragma once
// A viewer server on a free loopback port, serving on its own thread while a test runs; shared
// by the server's tests.

#include <chrono>
#include <thread>

#include "chronomap/view/server.h"
#include "test_support.h"
// After Eigen: httplib.h includes <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace chronomap::test {

/// Three random sessions, 1000 s apart.
inline TemporalMap threeSessions() {
  TemporalMap map(0.05);
  for (int s = 0; s < 3; ++s) map.add(1000.0 * (s + 1), randomSessionMap(200 + s, 20, 0.2));
  return map;
}

/// Default settings on a free port.
inline ServerSettings anyPort() {
  ServerSettings s;
  s.port = 0;
  return s;
}

/// Serves `map` on its own thread until destroyed; returns once the server answers.
class Running {
 public:
  explicit Running(const TemporalMap& map, ServerSettings s = anyPort()) : server_(map, "three.cmap", s) {
    port_ = server_.bind();
    thread_ = std::thread([this] { server_.serve(); });
    httplib::Client probe("127.0.0.1", port_);
    for (int i = 0; i < 200 && !probe.Get("/api/map"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ~Running() {
    server_.stop();
    thread_.join();
  }
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;
  int port() const { return port_; }
  const Server& server() const { return server_; }

 private:
  Server server_;
  int port_ = 0;
  std::thread thread_;
};

}  // namespace chronomap::test
