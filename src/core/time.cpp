#include "chronomap/core/time.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's civil-date algorithm).
int64_t daysFromCivil(int64_t y, unsigned m, unsigned d) {
  y -= m <= 2 ? 1 : 0;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<int64_t>(doe) - 719468;
}

void civilFromDays(int64_t z, int64_t& y, unsigned& m, unsigned& d) {
  z += 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const auto doe = static_cast<unsigned>(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  d = doy - (153 * mp + 2) / 5 + 1;
  m = mp < 10 ? mp + 3 : mp - 9;
  y = static_cast<int64_t>(yoe) + era * 400 + (m <= 2 ? 1 : 0);
}

bool isLeap(int64_t y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }

unsigned daysInMonth(int64_t y, unsigned m) {
  static constexpr unsigned kDays[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && isLeap(y) ? 29 : kDays[m - 1];
}

// Reads exactly `n` digits at `pos`.
bool digits(std::string_view s, size_t& pos, size_t n, int& out) {
  if (pos + n > s.size()) return false;
  int v = 0;
  for (size_t i = 0; i < n; ++i) {
    const char c = s[pos + i];
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  pos += n;
  out = v;
  return true;
}

bool parseIso(std::string_view s, double& out) {
  size_t p = 0;
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
  if (!digits(s, p, 4, year) || p >= s.size() || s[p++] != '-' || !digits(s, p, 2, month) || p >= s.size() ||
      s[p++] != '-' || !digits(s, p, 2, day)) {
    return false;
  }
  if (month < 1 || month > 12 || day < 1 || static_cast<unsigned>(day) > daysInMonth(year, static_cast<unsigned>(month))) {
    return false;
  }
  double fraction = 0.0;
  int offset_s = 0;
  if (p < s.size()) {
    if (s[p] != 'T' && s[p] != 't' && s[p] != ' ') return false;
    ++p;
    if (!digits(s, p, 2, hour) || p >= s.size() || s[p++] != ':' || !digits(s, p, 2, minute)) return false;
    if (p < s.size() && s[p] == ':') {
      ++p;
      if (!digits(s, p, 2, second)) return false;
      if (p < s.size() && (s[p] == '.' || s[p] == ',')) {
        ++p;
        double scale = 0.1;
        const size_t start = p;
        while (p < s.size() && s[p] >= '0' && s[p] <= '9') {
          fraction += (s[p] - '0') * scale;
          scale *= 0.1;
          ++p;
        }
        if (p == start) return false;
      }
    }
    if (hour > 23 || minute > 59 || second > 60) return false;
    if (p < s.size()) {
      if (s[p] == 'Z' || s[p] == 'z') {
        ++p;
      } else if (s[p] == '+' || s[p] == '-') {
        const int sign = s[p] == '+' ? 1 : -1;
        ++p;
        int oh = 0, om = 0;
        if (!digits(s, p, 2, oh)) return false;
        if (p < s.size() && s[p] == ':') ++p;
        if (p < s.size() && !digits(s, p, 2, om)) return false;
        if (oh > 23 || om > 59) return false;
        offset_s = sign * (oh * 3600 + om * 60);
      } else {
        return false;
      }
    }
    if (p != s.size()) return false;
  }
  const int64_t days = daysFromCivil(year, static_cast<unsigned>(month), static_cast<unsigned>(day));
  out = static_cast<double>(days * 86400 + hour * 3600 + minute * 60 + second - offset_s) + fraction;
  return true;
}

}  // namespace

double checkTime(double seconds, const std::string& what) {
  if (std::isnan(seconds)) throw UsageError(what + " is not a number (give seconds since the epoch)");
  if (seconds < kEarliestTime_s || seconds > kLatestTime_s) {
    throw UsageError(what + " lies outside the years 1 to 9999 (seconds since the epoch from " +
                     std::to_string(static_cast<int64_t>(kEarliestTime_s)) + " to " +
                     std::to_string(static_cast<int64_t>(kLatestTime_s)) + ")");
  }
  return seconds;
}

double parseTime(std::string_view text) {
  std::string_view s = text;
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  std::string quoted(1, '\'');
  quoted.append(text).push_back('\'');
  if (s.empty()) throw UsageError("empty time: give ISO-8601 (2012-03-01T10:00:00Z) or seconds since the epoch");
  // A plain number: seconds since the epoch (a date always has a '-' after four digits).
  if (s.size() < 5 || s[4] != '-') {
    double v = 0.0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc{} || end != s.data() + s.size() || !std::isfinite(v)) {
      throw UsageError("time " + quoted + " is neither ISO-8601 (2012-03-01T10:00:00Z) nor seconds since the epoch");
    }
    return checkTime(v, "time " + quoted);
  }
  double v = 0.0;
  if (!parseIso(s, v)) {
    throw UsageError("time " + quoted + " is not a valid ISO-8601 time (expected e.g. 2012-03-01T10:00:00Z)");
  }
  return checkTime(v, "time " + quoted);
}

std::string formatTime(double seconds) {
  if (!(seconds >= kEarliestTime_s && seconds <= kLatestTime_s)) return "invalid-time";
  const double whole = std::floor(seconds);
  auto millis = static_cast<int64_t>(std::llround((seconds - whole) * 1000.0));
  auto total = static_cast<int64_t>(whole);
  if (millis == 1000) {
    ++total;
    millis = 0;
  }
  int64_t days = total / 86400;
  int64_t rest = total % 86400;
  if (rest < 0) {
    rest += 86400;
    --days;
  }
  int64_t y = 0;
  unsigned m = 0, d = 0;
  civilFromDays(days, y, m, d);
  char buffer[48];
  const int h = static_cast<int>(rest / 3600), mi = static_cast<int>(rest / 60 % 60), se = static_cast<int>(rest % 60);
  if (millis != 0) {
    std::snprintf(buffer, sizeof buffer, "%04lld-%02u-%02uT%02d:%02d:%02d.%03lldZ", static_cast<long long>(y), m, d, h,
                  mi, se, static_cast<long long>(millis));
  } else {
    std::snprintf(buffer, sizeof buffer, "%04lld-%02u-%02uT%02d:%02d:%02dZ", static_cast<long long>(y), m, d, h, mi, se);
  }
  return buffer;
}

double hourOfDay(double time_s) {
  constexpr double kDay_s = 86400.0;
  double s = std::fmod(time_s, kDay_s);
  if (s < 0.0) s += kDay_s;
  return std::min(s / 3600.0, std::nextafter(24.0, 0.0));
}

}  // namespace chronomap
