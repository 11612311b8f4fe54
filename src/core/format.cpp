#include "chronomap/core/format.h"

#include <charconv>
#include <cstdio>

namespace chronomap {

std::string humanBytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 4) {
    bytes /= 1024.0;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof(buf), u == 0 ? "%.0f %s" : "%.1f %s", bytes, units[u]);
  return buf;
}

std::string formatNumber(double v) {
  char buf[32];
  const auto result = std::to_chars(buf, buf + sizeof(buf), v);  // 24 characters at most
  return std::string(buf, result.ptr);
}

}  // namespace chronomap
