#pragma once
// Shared helpers for the tests: the real-data folder, temporary folders, files, the command-line
// tool; the builders of test inputs are in builders.h.

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "builders.h"

namespace chronomap::test {

/// The folder of real recordings (CHRONOMAP_DATA_DIR, else ../shared/data beside the project).
std::filesystem::path dataDir();

/// True when tests run under CI (CI=true), where missing data is a failure, not a skip.
bool underCi();

/// A fresh temporary folder, removed when the object dies.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

/// Runs a shell command; returns its exit code and captures stdout and stderr.
struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};
CommandResult runCommand(const std::string& command);

/// The path of the chronomap command-line tool built with the tests.
std::string cli();

/// Every byte of a file (none when it cannot be read).
std::vector<uint8_t> bytesOf(const std::filesystem::path& path);

/// Writes exactly these bytes to a file, replacing it.
void writeBytes(const std::filesystem::path& path, const std::string& bytes);
void writeBytes(const std::filesystem::path& path, const std::vector<uint8_t>& bytes);

/// Runs `body` in a child process whose files may grow to `max_file_bytes` at most (a full disk:
/// writes past it fail with EFBIG, SIGXFSZ ignored). @return the exit code `body` returned, 99
/// when it threw, -1 when the child did not exit normally.
int exitCodeUnderFileSizeLimit(uint64_t max_file_bytes, const std::function<int()>& body);

/// Runs `body` in a child process that may map at most `extra_bytes` more address space than it
/// holds when it starts (RLIMIT_AS), so that a reader allocating what its input only claims fails
/// there (std::bad_alloc) instead of eating the machine's memory. Under AddressSanitizer or
/// ThreadSanitizer, which reserve terabytes of address space, the limit is not set; `body` runs
/// in the child all the same. @return as exitCodeUnderFileSizeLimit.
int exitCodeUnderMemoryLimit(uint64_t extra_bytes, const std::function<int()>& body);

/// False under AddressSanitizer or ThreadSanitizer, where exitCodeUnderMemoryLimit sets no limit.
bool memoryLimitsApply();

/// True in the AddressSanitizer and ThreadSanitizer builds, where every process runs several
/// times slower: tests that repeat a random trial many times run fewer rounds there (the Release
/// run keeps the full count).
bool underSanitizer();

/// A cloud-list dataset `dir/name.txt` of one cloud `dir/name.ply`: a 1 x 1 m wall of points
/// 0.02 m apart in the plane x = wall_x, seen from the origin. @return the list's path.
std::filesystem::path writeWallDataset(const std::filesystem::path& dir, const std::string& name, float wall_x);

}  // namespace chronomap::test

/// Resolves a path under the data folder into `var`; fails under CI and skips elsewhere when the
/// file is missing.
#define CHRONOMAP_REQUIRE_DATA(var, relative)                                                   \
  const std::filesystem::path var = ::chronomap::test::dataDir() / (relative);                  \
  if (!std::filesystem::exists(var)) {                                                          \
    if (::chronomap::test::underCi()) FAIL() << "missing test data under CI: " << var;          \
    GTEST_SKIP() << "test data not found: " << var << " (set CHRONOMAP_DATA_DIR)";              \
  }
