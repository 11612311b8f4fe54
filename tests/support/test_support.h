#pragma once
// Shared helpers for the tests: the real-data folder, temporary folders, small builders.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "chronomap/core/point_cloud.h"
#include "chronomap/octree/session_map.h"

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

/// A random session map over a side^3 block of voxels at the map origin: each voxel observed
/// with probability 0.9, occupied with probability `occupied`, free subtrees compressed.
SessionMap randomSessionMap(uint64_t seed, int side = 16, double occupied = 0.1, double resolution_m = 0.05);

/// A cloud of the given points (no colour).
PointCloud cloudOf(std::initializer_list<Eigen::Vector3f> points);

}  // namespace chronomap::test

/// Resolves a path under the data folder into `var`; fails under CI and skips elsewhere when the
/// file is missing.
#define CHRONOMAP_REQUIRE_DATA(var, relative)                                                   \
  const std::filesystem::path var = ::chronomap::test::dataDir() / (relative);                  \
  if (!std::filesystem::exists(var)) {                                                          \
    if (::chronomap::test::underCi()) FAIL() << "missing test data under CI: " << var;          \
    GTEST_SKIP() << "test data not found: " << var << " (set CHRONOMAP_DATA_DIR)";              \
  }
