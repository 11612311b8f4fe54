#pragma once
/// @file
/// How much memory this process may use, and what it was doing when it ran out: every memory
/// limit and every "out of memory" message starts here.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace chronomap {

/// The memory this process may really use: the smallest of the machine's physical memory, the
/// address-space limit (RLIMIT_AS) and the memory limit of its cgroup (v2 memory.max, v1
/// memory.limit_in_bytes). A default limit derived from it holds inside a container or under
/// `ulimit -v` as on a bare machine.
size_t processMemoryBytes();

/// The smallest of the limits that are set (physical memory is always known: 0 means unknown).
size_t smallestMemoryLimit(size_t physical_bytes, std::optional<uint64_t> address_space_bytes,
                           std::optional<uint64_t> cgroup_bytes);

/// A cgroup limit file's text ("max", or a number of bytes; numbers of 2^60 and more mean none).
std::optional<uint64_t> parseCgroupLimit(const std::string& text);

/// While one lives, running out of memory is reported as "out of memory while WHAT: ADVICE"
/// (describeError) instead of a bare "out of memory". Scopes nest; the innermost one speaks,
/// also after the exception has left it (the innermost scope it unwound is remembered until the
/// next outermost scope starts). Process-wide (a worker thread's std::bad_alloc reaches the
/// command that started it).
class MemoryActivity {
 public:
  MemoryActivity(std::string what, std::string advice);
  ~MemoryActivity();
  MemoryActivity(const MemoryActivity&) = delete;
  MemoryActivity& operator=(const MemoryActivity&) = delete;

 private:
  std::string previous_what_, previous_advice_;
  int exceptions_ = 0;
};

/// "out of memory", with the innermost MemoryActivity's words when one lives.
std::string outOfMemoryMessage();

/// A --memory-limit in GiB as bytes: 0 is no limit; any other value is at least one byte (a
/// tiny limit is a limit, never "none"). @throw UsageError naming `flag` for a negative,
/// non-finite or absurd value.
size_t memoryLimitFromGib(double gib, const std::string& flag = "--memory-limit");

}  // namespace chronomap
