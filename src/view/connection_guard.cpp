// The viewer's connections: a poll loop holds them until their request has arrived whole, a
// thread pool answers them (connection_guard.h says why).

#include "connection_guard.h"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace chronomap {

namespace {

using Clock = std::chrono::steady_clock;

// A request header this long without its end is handed over anyway, for cpp-httplib to refuse.
constexpr size_t kMaxHeaderBytes = 64 * 1024;
// Bytes read from a socket at a time.
constexpr size_t kChunkBytes = 4096;

void closeSocket(int fd) {
  shutdown(fd, SHUT_RDWR);
  close(fd);
}

// Waits until `fd` is ready for `events` or `deadline` passes. @return whether it is ready.
bool waitFor(int fd, short events, Clock::time_point deadline) {
  for (;;) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{fd, events, 0};
    const int n = poll(&p, 1, static_cast<int>(std::min<long long>(left, 1 << 30)));
    if (n > 0) return true;
    if (n < 0 && errno != EINTR) return false;
  }
}

// The numeric address and port of a socket's peer (or its own end).
void addressOf(int fd, bool peer, std::string& ip, int& port) {
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  const int rc = peer ? getpeername(fd, reinterpret_cast<sockaddr*>(&a), &len) : getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  char host[NI_MAXHOST] = "", service[NI_MAXSERV] = "";
  if (rc != 0 || getnameinfo(reinterpret_cast<sockaddr*>(&a), len, host, sizeof host, service, sizeof service,
                             NI_NUMERICHOST | NI_NUMERICSERV) != 0) {
    ip.clear();
    port = 0;
    return;
  }
  ip = host;
  port = std::atoi(service);
}

// One request's exchange for cpp-httplib: reads first what the lobby has read already, then the
// socket until the request's deadline; writes the whole answer or fails, waiting at most
// write_timeout for the client to take more and at most answer_timeout in all.
class DeadlineStream : public httplib::Stream {
 public:
  DeadlineStream(int fd, std::string received, const ConnectionLimits& limits)
      : fd_(fd),
        buffer_(std::move(received)),
        read_deadline_(Clock::now() + limits.request_timeout),
        answer_deadline_(Clock::now() + limits.answer_timeout),
        write_timeout_(limits.write_timeout) {}

  bool is_readable() const override { return pos_ < buffer_.size() || waitFor(fd_, POLLIN, read_deadline_); }
  bool is_writable() const override { return waitFor(fd_, POLLOUT, writeDeadline()); }

  ssize_t read(char* ptr, size_t size) override {
    if (pos_ == buffer_.size()) {
      buffer_.resize(kChunkBytes);
      pos_ = 0;
      ssize_t n = -1;
      while (n < 0 && waitFor(fd_, POLLIN, read_deadline_)) {
        n = recv(fd_, buffer_.data(), buffer_.size(), MSG_DONTWAIT);
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) break;
      }
      buffer_.resize(n > 0 ? static_cast<size_t>(n) : 0);
      if (n <= 0) return n;
    }
    const size_t k = std::min(size, buffer_.size() - pos_);
    std::memcpy(ptr, buffer_.data() + pos_, k);
    pos_ += k;
    return static_cast<ssize_t>(k);
  }

  // cpp-httplib writes a response's header with one call and does not check it: all or nothing.
  ssize_t write(const char* ptr, size_t size) override {
    size_t sent = 0;
    while (sent < size && waitFor(fd_, POLLOUT, writeDeadline())) {
      const ssize_t n = send(fd_, ptr + sent, size - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) sent += static_cast<size_t>(n);
      if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return -1;
    }
    return sent == size ? static_cast<ssize_t>(size) : -1;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override { addressOf(fd_, true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { addressOf(fd_, false, ip, port); }
  socket_t socket() const override { return fd_; }

  // What was read beyond the request: the start of the next one.
  std::string unread() const { return buffer_.substr(pos_); }

 private:
  Clock::time_point writeDeadline() const { return std::min(Clock::now() + write_timeout_, answer_deadline_); }

  int fd_;
  std::string buffer_;
  size_t pos_ = 0;
  Clock::time_point read_deadline_, answer_deadline_;
  std::chrono::milliseconds write_timeout_;
};

}  // namespace

/// A connection in the lobby: what it has sent of its next request, and until when it may send it.
struct GuardedHttpServer::Waiting {
  int fd = -1;
  std::string received;
  Clock::time_point since, deadline;
  size_t answered = 0;  ///< requests answered on it so far

  bool complete() const { return received.find("\r\n\r\n") != std::string::npos || received.size() >= kMaxHeaderBytes; }
};

/// One listen()'s task queue: cpp-httplib hands it each accepted connection (enqueue runs at
/// once, on the accept loop, and only passes the socket on); a thread polls the waiting ones and
/// hands those with a whole request to the pool.
class GuardedHttpServer::Lobby : public httplib::TaskQueue {
 public:
  Lobby(GuardedHttpServer& server, const ConnectionLimits& limits) : server_(server), limits_(limits), pool_(limits.threads) {
    if (pipe2(wake_, O_NONBLOCK | O_CLOEXEC) != 0) wake_[0] = wake_[1] = -1;
    thread_ = std::thread([this] { run(); });
  }
  ~Lobby() override {
    stop();
    for (int fd : wake_) {
      if (fd >= 0) close(fd);
    }
  }
  Lobby(const Lobby&) = delete;
  Lobby& operator=(const Lobby&) = delete;

  void enqueue(std::function<void()> fn) override { fn(); }

  void shutdown() override { stop(); }

  // Stops the loop and the pool (once); connections still open are closed.
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake();
    if (!thread_.joinable()) return;
    thread_.join();
    pool_.shutdown();
    server_.lobby_ = nullptr;
  }

  // Takes a connection in (new, or back after an answer); closes it when stopping.
  void admit(Waiting w) {
    const int fd = w.fd;
    bool taken = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!stopping_) {
        incoming_.push_back(std::move(w));
        taken = true;
      }
    }
    if (!taken) closeSocket(fd);
    wake();
  }

 private:
  void wake() {
    const char byte = 0;
    if (wake_[1] >= 0 && ::write(wake_[1], &byte, 1) < 0) return;  // a full pipe wakes the loop as well
  }

  void run() {
    std::vector<Waiting> waiting;
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (stopping_) break;
        for (auto& w : incoming_) waiting.push_back(std::move(w));
        incoming_.clear();
      }
      handOverOrDrop(waiting);
      dropOverLimit(waiting);
      pollOnce(waiting);
    }
    for (const auto& w : waiting) closeSocket(w.fd);
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& w : incoming_) closeSocket(w.fd);
    incoming_.clear();
  }

  // Moves waiting[from] to waiting[to] (to <= from) while compacting the list in place.
  static void keepAt(std::vector<Waiting>& waiting, size_t to, size_t from) {
    if (to != from) waiting[to] = std::move(waiting[from]);
  }

  // Over the limit, the connections that have waited longest are closed.
  void dropOverLimit(std::vector<Waiting>& waiting) const {
    if (waiting.size() <= limits_.max_waiting) return;
    std::sort(waiting.begin(), waiting.end(), [](const Waiting& a, const Waiting& b) { return a.since < b.since; });
    const auto excess = static_cast<std::ptrdiff_t>(waiting.size() - limits_.max_waiting);
    for (auto it = waiting.begin(); it != waiting.begin() + excess; ++it) closeSocket(it->fd);
    waiting.erase(waiting.begin(), waiting.begin() + excess);
  }

  // Whole requests go to the pool; connections past their deadline are closed.
  void handOverOrDrop(std::vector<Waiting>& waiting) {
    const auto now = Clock::now();
    size_t kept = 0;
    for (size_t i = 0; i < waiting.size(); ++i) {
      Waiting& w = waiting[i];
      if (w.complete()) {
        pool_.enqueue([this, task = std::make_shared<Waiting>(std::move(w))] { server_.answer(*this, std::move(*task)); });
      } else if (now >= w.deadline) {
        closeSocket(w.fd);
      } else {
        keepAt(waiting, kept++, i);
      }
    }
    waiting.resize(kept);
  }

  // Waits for bytes on any waiting connection (or a wake-up, or the nearest deadline) and reads
  // them; a connection that closes or fails is closed.
  void pollOnce(std::vector<Waiting>& waiting) {
    std::vector<pollfd> fds{{wake_[0], POLLIN, 0}};
    auto until = Clock::now() + std::chrono::seconds(1);
    for (const auto& w : waiting) {
      fds.push_back({w.fd, POLLIN, 0});
      until = std::min(until, w.deadline);
    }
    const auto wait_ms = std::chrono::ceil<std::chrono::milliseconds>(until - Clock::now()).count();
    if (poll(fds.data(), fds.size(), static_cast<int>(std::max<long long>(wait_ms, 0))) <= 0) return;
    char chunk[kChunkBytes];
    if (fds[0].revents != 0) {
      while (::read(wake_[0], chunk, sizeof chunk) == static_cast<ssize_t>(sizeof chunk)) {
      }
    }
    size_t kept = 0;
    for (size_t i = 0; i < waiting.size(); ++i) {
      Waiting& w = waiting[i];
      if (fds[i + 1].revents != 0) {
        const ssize_t n = recv(w.fd, chunk, sizeof chunk, MSG_DONTWAIT);
        if (n > 0) w.received.append(chunk, static_cast<size_t>(n));
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
          closeSocket(w.fd);
          continue;
        }
      }
      keepAt(waiting, kept++, i);
    }
    waiting.resize(kept);
  }

  GuardedHttpServer& server_;
  ConnectionLimits limits_;
  httplib::ThreadPool pool_;
  int wake_[2] = {-1, -1};
  std::mutex mutex_;
  bool stopping_ = false;
  std::vector<Waiting> incoming_;
  std::thread thread_;
};

GuardedHttpServer::GuardedHttpServer(ConnectionLimits limits) : limits_(limits) {
  new_task_queue = [this] {
    lobby_ = new Lobby(*this, limits_);
    return lobby_;
  };
}

void GuardedHttpServer::widenBacklog() {
  // listen() again on a listening socket only changes its backlog.
  if (svr_sock_ != INVALID_SOCKET) ::listen(svr_sock_, limits_.listen_backlog);
}

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  Waiting w;
  w.fd = sock;
  w.since = Clock::now();
  w.deadline = w.since + limits_.request_timeout;
  if (lobby_) {
    lobby_->admit(std::move(w));
  } else {
    closeSocket(sock);
  }
  return true;
}

void GuardedHttpServer::answer(Lobby& lobby, Waiting w) {
  DeadlineStream stream(w.fd, std::move(w.received), limits_);
  const bool last = w.answered + 1 >= keep_alive_max_count_;
  bool closed = false;
  bool ok = false;
  try {
    ok = process_request(stream, last, closed, [](httplib::Request&) {});
  } catch (...) {
    // Out of memory while reading or writing (handlers' exceptions are the base class's): this
    // connection ends, the server goes on.
  }
  if (!ok || last || closed) {
    closeSocket(w.fd);
    return;
  }
  w.received = stream.unread();
  w.since = Clock::now();
  w.deadline = w.since + limits_.keep_alive_timeout;
  ++w.answered;
  lobby.admit(std::move(w));
}

}  // namespace chronomap
