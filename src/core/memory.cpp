#include "chronomap/core/memory.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <fstream>
#include <mutex>
#include <sstream>
#include <utility>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

std::mutex activity_mutex;
std::string activity_what, activity_advice;
int activity_depth = 0;
// The innermost activity an exception left (its scope unwound by it), for the message that
// describes the exception once it reaches the command line.
std::string failed_what, failed_advice;

std::string readFirstLine(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

/// This process's cgroup memory limit: v2 ("0::/path" in /proc/self/cgroup, memory.max) or v1
/// (the "memory" controller's memory.limit_in_bytes), with the mount's root as a fallback.
std::optional<uint64_t> cgroupLimit() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  std::optional<uint64_t> out;
  auto consider = [&out](const std::string& file) {
    const std::optional<uint64_t> v = parseCgroupLimit(readFirstLine(file));
    if (v && (!out || *v < *out)) out = v;
  };
  while (std::getline(in, line)) {
    const size_t a = line.find(':'), b = line.find(':', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1), path = line.substr(b + 1);
    if (controllers.empty()) {
      consider("/sys/fs/cgroup" + path + "/memory.max");
    } else if (controllers.find("memory") != std::string::npos) {
      consider("/sys/fs/cgroup/memory" + path + "/memory.limit_in_bytes");
      consider("/sys/fs/cgroup/memory/memory.limit_in_bytes");
    }
  }
  return out;
}

}  // namespace

std::optional<uint64_t> parseCgroupLimit(const std::string& text) {
  if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos) return std::nullopt;  // "max"
  if (text.size() > 19) return std::nullopt;
  const uint64_t v = std::stoull(text);
  if (v == 0 || v >= (uint64_t{1} << 60)) return std::nullopt;
  return v;
}

size_t smallestMemoryLimit(size_t physical_bytes, std::optional<uint64_t> address_space_bytes,
                           std::optional<uint64_t> cgroup_bytes) {
  uint64_t out = physical_bytes == 0 ? UINT64_MAX : physical_bytes;
  if (address_space_bytes) out = std::min(out, *address_space_bytes);
  if (cgroup_bytes) out = std::min(out, *cgroup_bytes);
  return out == UINT64_MAX ? 0 : static_cast<size_t>(out);
}

size_t processMemoryBytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page_bytes = ::sysconf(_SC_PAGE_SIZE);
  const size_t physical = pages > 0 && page_bytes > 0 ? static_cast<size_t>(pages) * static_cast<size_t>(page_bytes) : 0;
  std::optional<uint64_t> address_space;
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) address_space = limit.rlim_cur;
  return smallestMemoryLimit(physical, address_space, cgroupLimit());
}

MemoryActivity::MemoryActivity(std::string what, std::string advice) : exceptions_(std::uncaught_exceptions()) {
  std::lock_guard<std::mutex> lock(activity_mutex);
  if (activity_depth++ == 0) failed_what.clear(), failed_advice.clear();
  previous_what_ = std::exchange(activity_what, std::move(what));
  previous_advice_ = std::exchange(activity_advice, std::move(advice));
}

MemoryActivity::~MemoryActivity() {
  std::lock_guard<std::mutex> lock(activity_mutex);
  --activity_depth;
  if (std::uncaught_exceptions() > exceptions_ && failed_what.empty()) {
    failed_what = activity_what;
    failed_advice = activity_advice;
  }
  activity_what = std::move(previous_what_);
  activity_advice = std::move(previous_advice_);
}

std::string outOfMemoryMessage() {
  std::lock_guard<std::mutex> lock(activity_mutex);
  const bool failed = !failed_what.empty();
  const std::string& what = failed ? failed_what : activity_what;
  const std::string& advice = failed ? failed_advice : activity_advice;
  std::string out = "out of memory";
  if (!what.empty()) out += " while " + what;
  if (!advice.empty()) out += ": " + advice;
  return out;
}

size_t memoryLimitFromGib(double gib, const std::string& flag) {
  if (!std::isfinite(gib) || gib < 0.0 || gib > 1e6) {
    std::ostringstream msg;
    msg << flag << " must be a number of GiB (0 for no limit), not " << gib;
    throw UsageError(msg.str());
  }
  if (gib == 0.0) return 0;
  return std::max<size_t>(1, static_cast<size_t>(std::llround(gib * 1073741824.0)));
}

}  // namespace chronomap
