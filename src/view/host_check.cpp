// Which Host headers the viewer's server answers, and the warning for serving beyond loopback.
// A web page of any site can make the browser send requests to 127.0.0.1 under the page's own
// name once that name resolves there (DNS rebinding); the browser then lets the page read the
// answers. The Host header carries that name, so answering only our own names closes it.

#include <arpa/inet.h>
#include <netinet/in.h>

#include <algorithm>
#include <cctype>
#include <cstring>

#include "chronomap/view/server.h"
#include "printable.h"

namespace chronomap {

namespace {

// `host` without the brackets of an IPv6 literal.
std::string unbracketed(const std::string& host) {
  return host.size() >= 2 && host.front() == '[' && host.back() == ']' ? host.substr(1, host.size() - 2) : host;
}

std::string lowercase(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// An address literal's family and bytes (IPv4 dotted quad or IPv6), if `text` is one.
struct Address {
  int family = AF_UNSPEC;
  unsigned char bytes[16] = {};
};
std::optional<Address> addressLiteral(const std::string& text) {
  Address a;
  if (inet_pton(AF_INET, text.c_str(), a.bytes) == 1) {
    a.family = AF_INET;
  } else if (inet_pton(AF_INET6, text.c_str(), a.bytes) == 1) {
    a.family = AF_INET6;
  } else {
    return std::nullopt;
  }
  return a;
}

bool isWildcard(const std::string& host) {
  const auto a = addressLiteral(unbracketed(host));
  return host.empty() || (a && std::all_of(std::begin(a->bytes), std::end(a->bytes), [](unsigned char b) { return b == 0; }));
}

// The name or address of a Host header ("name", "name:port", "1.2.3.4:port", "[v6]:port"), or
// nothing when it is not of that form.
std::optional<std::string> hostName(const std::string& header) {
  std::string name, rest;
  if (!header.empty() && header.front() == '[') {
    const size_t close = header.find(']');
    if (close == std::string::npos) return std::nullopt;
    name = header.substr(1, close - 1);
    rest = header.substr(close + 1);
    const auto a = addressLiteral(name);
    if (!a || a->family != AF_INET6) return std::nullopt;
  } else {
    const size_t colon = header.find(':');
    name = header.substr(0, colon);
    rest = colon == std::string::npos ? "" : header.substr(colon);
    const auto hostChar = [](unsigned char c) { return std::isalnum(c) || c == '.' || c == '-' || c == '_'; };
    if (name.empty() || !std::all_of(name.begin(), name.end(), hostChar)) return std::nullopt;
  }
  if (!rest.empty()) {
    const auto digits = rest.substr(1);
    if (rest[0] != ':' || digits.empty() || digits.size() > 5 ||
        !std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); })) {
      return std::nullopt;
    }
  }
  return lowercase(name);
}

// Whether a Host header's name is the served host: the same address, or the same name.
bool sameHost(const std::string& name, const std::string& served_host) {
  const std::string served = lowercase(unbracketed(served_host));
  const auto a = addressLiteral(name), b = addressLiteral(served);
  if (a && b) return a->family == b->family && std::memcmp(a->bytes, b->bytes, sizeof a->bytes) == 0;
  return name == served;
}

}  // namespace

bool isLoopbackHost(const std::string& host) {
  const std::string h = lowercase(unbracketed(host));
  if (h == "localhost") return true;
  const auto a = addressLiteral(h);
  if (!a) return false;
  if (a->family == AF_INET) return a->bytes[0] == 127;
  const unsigned char loopback6[16] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
  const unsigned char mapped_prefix[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
  return std::memcmp(a->bytes, loopback6, 16) == 0 || (std::memcmp(a->bytes, mapped_prefix, 12) == 0 && a->bytes[12] == 127);
}

std::optional<std::string> hostRefusal(const std::string& host_header, const std::string& served_host) {
  const auto name = hostName(host_header);
  if (name) {
    if (isLoopbackHost(*name) || sameHost(*name, served_host)) return std::nullopt;
    // On every interface the server is reached by any of the machine's addresses; an address
    // cannot be rebound, only a name can.
    if (isWildcard(served_host) && addressLiteral(*name)) return std::nullopt;
  }
  const std::string served = isWildcard(served_host) ? served_host + ", any address of this machine" : served_host;
  return (host_header.empty() ? std::string("a request without a Host header") : "Host '" + printable(host_header) + "'") +
         " is refused: chronomap view answers only requests addressed to localhost, 127.0.0.1, [::1] or the address it "
         "serves on (" + served + "), so that a web page of another site cannot read the map under a name it points at "
         "this machine (DNS rebinding). Open the viewer at one of those addresses, or, to use another name of this "
         "machine, start chronomap view with --host NAME.";
}

std::optional<std::string> exposureWarning(const std::string& host, int port) {
  if (isLoopbackHost(host)) return std::nullopt;
  const std::string p = std::to_string(port);
  return "warning: --host " + host + " serves the map beyond this machine: anyone who can reach this machine on port " +
         p + " can read the map and the rooms it scanned (the viewer has no authentication and no encryption). To view it "
         "from another machine, keep the default 127.0.0.1 and use an SSH tunnel: ssh -L " + p + ":localhost:" + p +
         " THIS-MACHINE, then open http://localhost:" + p + "/ there.";
}

}  // namespace chronomap
