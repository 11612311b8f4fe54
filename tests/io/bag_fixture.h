#pragma once
// Shared by the ROS 1 and ROS 2 bag tests: a simulated TUM session (the tiny preset at 160 x 120)
// in a temporary folder, the bags a suite writes from it once, and how the tests read them.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "chronomap/io/cmap.h"
#include "chronomap/io/dataset.h"
#include "chronomap/pipeline/session.h"
#include "test_support.h"

namespace chronomap::io {

/// `Suite` names the writers its bags need in `Suite::kWriters` and writes them in its
/// SetUpTestSuite(), after simulate(), recording any failure in generator_error_: every test of
/// the suite then fails under CI=true and is skipped elsewhere.
template <class Suite>
class BagFixture : public ::testing::Test {
 protected:
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (generator_error_.empty()) return;
    if (test::underCi()) FAIL() << "writing the test bags failed: " << generator_error_;
    GTEST_SKIP() << "writing the test bags failed (" << Suite::kWriters << " missing?): " << generator_error_;
  }

  /// The temporary folder and the simulated session in it.
  static void simulate() {
    dir_ = new test::TempDir();
    const auto simulated = test::runCommand(test::cli() + " simulate --preset tiny --sessions 1 --resolution-scale 0.25 -o " +
                                            (*dir_ / "sim").string());
    ASSERT_EQ(simulated.exit_code, 0) << simulated.err;
  }

  static std::filesystem::path tum() { return *dir_ / "sim" / "session_00"; }
  static std::filesystem::path bags() { return *dir_ / "bags"; }
  static std::filesystem::path bag(const std::string& name) { return bags() / name; }

  /// The bags keep the TUM PNG's units (5000 per metre) in their 16UC1 images.
  static DatasetSettings bagSettings() {
    DatasetSettings s;
    s.depth_scale = 5000.0;
    return s;
  }
  static std::vector<uint8_t> mapBytes(const std::filesystem::path& path, const DatasetSettings& dataset) {
    pipeline::SessionSettings s;
    s.dataset = dataset;
    s.integrator.threads = 2;
    return encodeSessionMap(pipeline::integrateDataset(path, s).map, nlohmann::json::object());
  }

  static inline test::TempDir* dir_ = nullptr;
  static inline std::string generator_error_;
};

}  // namespace chronomap::io
