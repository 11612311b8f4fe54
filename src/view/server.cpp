// The viewer's HTTP server: cpp-httplib in front of Api, behind a request guard.

#include "chronomap/view/server.h"

#include <sys/socket.h>
#include <zlib.h>

#include <chrono>

#include "chronomap/core/error.h"
#include "connection_guard.h"

namespace chronomap {

namespace {

// `bytes` as a gzip stream (zlib, best compression).
std::string gzip(std::string_view bytes) {
  z_stream z{};
  if (deflateInit2(&z, Z_BEST_COMPRESSION, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::runtime_error("zlib: deflateInit2 failed");
  }
  std::string out(deflateBound(&z, bytes.size()), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
  z.avail_in = static_cast<uInt>(bytes.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  if (rc != Z_STREAM_END) throw std::runtime_error("zlib: deflate did not finish");
  return out;
}

// The server's connection limits, checked.
ConnectionLimits connectionLimits(const ServerSettings& s) {
  const auto ms = [](double seconds, const char* what) {
    if (!(seconds > 0.0 && seconds <= 86400.0)) {
      throw UsageError(std::string("the viewer's ") + what + " must be between 0 and 86400 s, not " + std::to_string(seconds));
    }
    return std::chrono::milliseconds(std::max<int64_t>(1, static_cast<int64_t>(seconds * 1000.0)));
  };
  if (s.threads < 1 || s.max_open_connections < 1) {
    throw UsageError("the viewer needs at least one thread and one open connection (threads " + std::to_string(s.threads) +
                     ", connections " + std::to_string(s.max_open_connections) + ")");
  }
  ConnectionLimits limits;
  limits.request_timeout = ms(s.request_timeout_s, "request timeout");
  limits.keep_alive_timeout = ms(s.keep_alive_timeout_s, "keep-alive timeout");
  limits.write_timeout = ms(s.write_timeout_s, "write timeout");
  limits.threads = static_cast<size_t>(s.threads);
  limits.max_waiting = s.max_open_connections;
  return limits;
}

// The request guard, in front of every route: a request addressed to another name than ours is
// refused before anything answers it (hostRefusal).
httplib::Server::HandlerResponse guardRequest(const std::string& served_host, const httplib::Request& req, httplib::Response& res) {
  std::optional<std::string> refusal;
  if (req.get_header_value_count("Host") > 1) {
    refusal = "a request with more than one Host header is refused";
  } else {
    refusal = hostRefusal(req.get_header_value("Host"), served_host);
  }
  if (!refusal) return httplib::Server::HandlerResponse::Unhandled;
  res.status = 403;
  res.set_header("Cache-Control", "no-store");
  res.set_content(nlohmann::json{{"error", *refusal}}.dump(), "application/json");
  return httplib::Server::HandlerResponse::Handled;
}

// The largest request body read: the API takes none.
constexpr size_t kMaxRequestBody = 64 * 1024;

}  // namespace

struct Server::Impl {
  Impl(const TemporalMap& map, std::string name, ServerSettings s)
      : api(map, std::move(name), s.api), settings(std::move(s)), http(connectionLimits(settings)) {}
  Api api;
  ServerSettings settings;
  // The page's script, compressed once: cpp-httplib would compress it per request (with Brotli
  // at its slowest setting: 3 s for the 0.6 MB bundle).
  std::string script_gz = gzip(viewerScript());
  GuardedHttpServer http;
  int port = -1;
};

Server::Server(const TemporalMap& map, std::string name, ServerSettings settings)
    : impl_(std::make_unique<Impl>(map, std::move(name), std::move(settings))) {
  const Api& api = impl_->api;
  const std::string& script_gz = impl_->script_gz;
  auto answer = [&api, &script_gz](const httplib::Request& req, httplib::Response& res) {
    if (req.path == "/viewer.js" && req.params.empty()) {
      res.set_header("Cache-Control", "no-store");
      // A content type cpp-httplib does not compress again (it compares the whole value).
      if (req.get_header_value("Accept-Encoding").find("gzip") != std::string::npos) {
        res.set_header("Content-Encoding", "gzip");
        res.set_content(script_gz, "application/javascript; charset=utf-8");
      } else {
        res.set_content(std::string(viewerScript()), "application/javascript; charset=utf-8");
      }
      return;
    }
    Query query(req.params.begin(), req.params.end());
    Reply r = api.get(req.path, query);
    res.status = r.status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(std::move(r.body), r.content_type.c_str());
  };
  impl_->http.Get(R"(/.*)", answer);
  impl_->http.set_pre_routing_handler([&host = impl_->settings.host](const httplib::Request& req, httplib::Response& res) {
    return guardRequest(host, req, res);
  });
  impl_->http.set_payload_max_length(kMaxRequestBody);
  // cpp-httplib's default also sets SO_REUSEPORT, with which a second server (another `chronomap
  // view`, or another program) could bind the same port and take some of the connections. Only
  // SO_REUSEADDR: a restarted server may bind while old connections linger in TIME_WAIT.
  impl_->http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  // Other methods, and paths the router never matches, get a 404 or 405 from cpp-httplib; a
  // handler that throws (out of memory) gets a 500 and the server keeps serving.
  impl_->http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
    res.status = 500;
    res.set_content(R"({"error":"internal error"})", "application/json");
  });
}

Server::~Server() { stop(); }

int Server::bind() {
  auto& s = impl_->settings;
  impl_->port = s.port == 0 ? impl_->http.bind_to_any_port(s.host) : (impl_->http.bind_to_port(s.host, s.port) ? s.port : -1);
  if (impl_->port < 0) {
    throw IoError("cannot listen on " + s.host + ":" + std::to_string(s.port) + " (in use, or not an address of this machine)");
  }
  impl_->http.widenBacklog();
  return impl_->port;
}

void Server::serve() {
  if (impl_->port < 0) throw UsageError("Server::serve() before bind()");
  if (!impl_->http.listen_after_bind()) {
    // stop() makes listen return false as well; only a failure without it is an error.
    if (impl_->http.is_running()) throw IoError("the server stopped listening on " + url());
  }
}

void Server::stop() {
  if (impl_ && impl_->http.is_running()) impl_->http.stop();
}

std::string Server::url() const {
  const std::string& host = impl_->settings.host;
  const bool v6 = host.find(':') != std::string::npos;
  std::string u = "http://";
  u.append(v6 ? "[" : "").append(host).append(v6 ? "]" : "").append(":").append(std::to_string(impl_->port)).append("/");
  return u;
}

}  // namespace chronomap
