// The viewer's server on a developer's machine: requests addressed to a name other than the
// loopback names or the served address are refused (DNS rebinding), slow clients cannot hold
// the others out, and `chronomap view --host` beyond loopback warns.

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "chronomap/store/temporal_file.h"
#include "chronomap/view/server.h"
#include "running_server.h"
#include "test_support.h"

namespace chronomap {
namespace {

using test::Running;
using test::threeSessions;

// The status and body of GET `path` sent to the server with the Host header `host`.
std::pair<int, std::string> getWithHost(int port, const std::string& host, const std::string& path = "/api/map") {
  httplib::Client c("127.0.0.1", port);
  c.set_read_timeout(5);
  const auto res = c.Get(path.c_str(), httplib::Headers{{"Host", host}});
  return res ? std::pair{res->status, res->body} : std::pair{-1, std::string()};
}

// A web page of another site whose name the attacker rebinds to 127.0.0.1 sends that name as
// the Host: refused on every route, with a reason. Loopback names and the served address, with
// or without a port (any port: an SSH tunnel forwards another), are answered.
TEST(ViewServerGuard, RefusesRebindingHostNamesOnEveryRoute) {
  const TemporalMap map = threeSessions();
  Running r(map);
  const std::string port = ":" + std::to_string(r.port());
  for (const std::string& host : std::vector<std::string>{"rebind.attacker.example" + port, "rebind.attacker.example", "localhost.attacker.example" + port,
                                 "127.0.0.1.nip.io" + port, "10.0.0.7" + port, "[::2]" + port, "127.0.0.1:80x", "::1",
                                 "localhost:" + port, ""}) {
    for (const char* path : {"/", "/viewer.js", "/api/map", "/api/snapshot?session=0", "/api/history?key=1,2,3", "/no/such/path"}) {
      const auto [status, body] = getWithHost(r.port(), host, path);
      EXPECT_EQ(status, 403) << host << " " << path;
      if (std::string(path) == "/api/map") {
        EXPECT_NE(body.find("DNS rebinding"), std::string::npos) << body;
        EXPECT_NE(body.find("--host"), std::string::npos) << body;
      }
    }
  }
  for (const std::string& host : std::vector<std::string>{"127.0.0.1" + port, "127.0.0.1", "localhost" + port, "LocalHost", "[::1]" + port, "[::1]",
                                 "127.0.0.2" + port, "localhost:9000"}) {
    const auto [status, body] = getWithHost(r.port(), host);
    EXPECT_EQ(status, 200) << host << ": " << body;
  }
}

// Served on every interface, the server is reached by any of the machine's addresses: an
// address literal cannot be rebound, a name still can.
TEST(ViewServerGuard, ServedOnEveryInterfaceAcceptsAddressesButNotNames) {
  const TemporalMap map = threeSessions();
  ServerSettings s = test::anyPort();
  s.host = "0.0.0.0";
  Running r(map, s);
  const std::string port = ":" + std::to_string(r.port());
  for (const std::string& host : std::vector<std::string>{"0.0.0.0" + port, "192.0.2.10" + port, "[2001:db8::1]" + port, "localhost" + port}) {
    EXPECT_EQ(getWithHost(r.port(), host).first, 200) << host;
  }
  for (const std::string& host : std::vector<std::string>{"rebind.attacker.example" + port, "192.0.2.10.nip.io" + port}) {
    EXPECT_EQ(getWithHost(r.port(), host).first, 403) << host;
  }
}

// The rule alone, for served addresses a test cannot bind.
TEST(ViewServerGuard, TheHostRuleAcceptsLoopbackAndTheServedAddressOnly) {
  EXPECT_FALSE(hostRefusal("192.168.1.5:8765", "192.168.1.5"));
  EXPECT_FALSE(hostRefusal("192.168.1.5", "192.168.1.5"));
  EXPECT_FALSE(hostRefusal("MyBox.lan:8765", "mybox.lan"));
  EXPECT_FALSE(hostRefusal("[fe80::1]:8765", "fe80:0::1"));
  EXPECT_FALSE(hostRefusal("localhost:8765", "192.168.1.5"));
  const auto other = hostRefusal("192.168.1.6:8765", "192.168.1.5");
  ASSERT_TRUE(other);
  EXPECT_NE(other->find("'192.168.1.6:8765'"), std::string::npos) << *other;
  EXPECT_NE(other->find("192.168.1.5"), std::string::npos) << *other;
  EXPECT_TRUE(hostRefusal("mybox.lan.attacker.example", "mybox.lan"));
  EXPECT_TRUE(hostRefusal("192.168.1.5:8765:1", "192.168.1.5"));
  EXPECT_TRUE(hostRefusal(std::string("localhost\0.attacker.example", 26), "127.0.0.1"));
  EXPECT_TRUE(isLoopbackHost("127.0.0.1"));
  EXPECT_TRUE(isLoopbackHost("127.1.2.3"));
  EXPECT_TRUE(isLoopbackHost("localhost"));
  EXPECT_TRUE(isLoopbackHost("::1"));
  EXPECT_FALSE(isLoopbackHost("0.0.0.0"));
  EXPECT_FALSE(isLoopbackHost("::"));
  EXPECT_FALSE(isLoopbackHost("192.168.1.5"));
  EXPECT_FALSE(isLoopbackHost("mybox.lan"));
}

// A TCP connection to the server on loopback.
int connectTo(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (fd >= 0 && connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) return fd;
  if (fd >= 0) close(fd);
  return -1;
}

// Clients that send the start of a request and then one more header byte every 200 ms, never
// finishing it (slowloris), until destroyed.
class SlowClients {
 public:
  SlowClients(int port, int count) {
    for (int i = 0; i < count; ++i) {
      const int fd = connectTo(port);
      if (fd < 0) continue;
      const std::string start = "GET /api/map HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ";
      if (send(fd, start.data(), start.size(), MSG_NOSIGNAL) > 0) fds_.push_back(fd);
    }
    trickle_ = std::thread([this] {
      for (int tick = 0; !done_; ++tick) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        if (tick % 20 != 0) continue;
        for (int fd : fds_) send(fd, "a", 1, MSG_NOSIGNAL);
      }
    });
  }
  ~SlowClients() {
    done_ = true;
    trickle_.join();
    for (int fd : fds_) close(fd);
  }
  SlowClients(const SlowClients&) = delete;
  SlowClients& operator=(const SlowClients&) = delete;
  size_t count() const { return fds_.size(); }
  // How many of the connections the server has closed (a read returns end of file or a reset).
  int closedByServer() const {
    int closed = 0;
    for (int fd : fds_) {
      char byte = 0;
      const ssize_t n = recv(fd, &byte, 1, MSG_DONTWAIT);
      if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) ++closed;
    }
    return closed;
  }

 private:
  std::vector<int> fds_;
  std::atomic<bool> done_{false};
  std::thread trickle_;
};

// The seconds a normal client waits for /api/map, or -1 when it gets no answer within 2 s.
double secondsForAnAnswer(int port) {
  httplib::Client c("127.0.0.1", port);
  c.set_connection_timeout(2);
  c.set_read_timeout(2);
  const auto start = std::chrono::steady_clock::now();
  const auto res = c.Get("/api/map");
  if (!res || res->status != 200) return -1;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Before, 8 such clients held the 8 threads of cpp-httplib's pool for as long as they kept
// trickling (its 5 s timeout is per read), and every other request waited behind them.
TEST(ViewServerGuard, SlowClientsDoNotHoldOthersOut) {
  const TemporalMap map = threeSessions();
  Running r(map);
  SlowClients slow(r.port(), 20);
  ASSERT_EQ(slow.count(), 20u);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the server has taken them all in
  for (int i = 0; i < 3; ++i) {
    const double s = secondsForAnAnswer(r.port());
    EXPECT_GE(s, 0.0) << "request " << i << " got no answer within 2 s";
    EXPECT_LT(s, 1.0) << "request " << i;
  }
  EXPECT_EQ(slow.closedByServer(), 0);  // within their time, they are kept
}

// More slow connections than the server holds open: the ones held longest are closed, and a
// normal client is still answered; one that takes longer than its time is dropped.
TEST(ViewServerGuard, ConnectionsOverTheLimitOrTheirTimeAreClosed) {
  const TemporalMap map = threeSessions();
  ServerSettings s = test::anyPort();
  s.max_open_connections = 4;
  s.request_timeout_s = 0.5;
  Running r(map, s);
  SlowClients slow(r.port(), 10);
  ASSERT_EQ(slow.count(), 10u);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_GE(slow.closedByServer(), 6);
  EXPECT_GE(secondsForAnAnswer(r.port()), 0.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  EXPECT_EQ(slow.closedByServer(), 10);
}

// cpp-httplib let the kernel queue 5 connections before its accept loop took them; in a burst
// (20 slow clients connecting at once) the rest waited a second each for their client to try
// again. Bound but not yet serving, the server's queue holds a burst of 20.
TEST(ViewServerGuard, ABurstOfConnectionsIsQueuedNotDropped) {
  const TemporalMap map = threeSessions();
  Server server(map, "three.cmap", test::anyPort());
  const int port = server.bind();
  std::vector<int> fds;
  for (int i = 0; i < 20; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    fds.push_back(fd);
  }
  int connected = 0;
  for (int fd : fds) {
    pollfd p{fd, POLLOUT, 0};
    int error = 0;
    socklen_t len = sizeof error;
    if (poll(&p, 1, 300) == 1 && getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &len) == 0 && error == 0) ++connected;
    close(fd);
  }
  EXPECT_EQ(connected, 20);
}

// `chronomap view MAP ARGS...` in a child process, its standard output and error in files.
class ViewProcess {
 public:
  ViewProcess(const test::TempDir& dir, const std::vector<std::string>& args) : out_(dir / "view.out"), err_(dir / "view.err") {
    pid_ = fork();
    if (pid_ == 0) {
      std::freopen(out_.c_str(), "w", stdout);
      std::freopen(err_.c_str(), "w", stderr);
      std::vector<char*> argv{const_cast<char*>("chronomap"), const_cast<char*>("view")};
      for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      execv(test::cli().c_str(), argv.data());
      _exit(127);
    }
  }
  ~ViewProcess() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
  }
  ViewProcess(const ViewProcess&) = delete;
  ViewProcess& operator=(const ViewProcess&) = delete;
  // Waits for the address line on standard output (up to 10 s) and returns it.
  std::string addressLine() const {
    std::string line;
    for (int i = 0; i < 500 && line.find("http://") == std::string::npos; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      std::ifstream f(out_);
      std::getline(f, line);
    }
    return line;
  }
  std::string errors() const {
    std::ifstream f(err_);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
  }

 private:
  std::string out_, err_;
  pid_t pid_ = -1;
};

TEST(ViewServerGuard, HostBeyondLoopbackWarnsOnStandardError) {
  test::TempDir dir;
  writeTemporalMap(dir / "three.cmap", threeSessions(), {});
  const std::string map = (dir / "three.cmap").string();
  {
    ViewProcess open(dir, {map, "--port", "0", "--host", "0.0.0.0"});
    EXPECT_NE(open.addressLine().find("http://0.0.0.0:"), std::string::npos);
    const std::string err = open.errors();
    EXPECT_NE(err.find("warning: --host 0.0.0.0"), std::string::npos) << err;
    EXPECT_NE(err.find("anyone who can reach this machine"), std::string::npos) << err;
    EXPECT_NE(err.find("no authentication"), std::string::npos) << err;
  }
  for (const char* host : {"127.0.0.1", "localhost"}) {
    ViewProcess local(dir, {map, "--port", "0", "--host", host});
    EXPECT_NE(local.addressLine().find("http://"), std::string::npos);
    EXPECT_EQ(local.errors(), "") << host;
  }
}

}  // namespace
}  // namespace chronomap
