#pragma once
// Shared by the ROS 1 and ROS 2 bag tests: a simulated TUM session (the tiny preset at 160 x 120)
// and the bags written from it, made once per build in the build folder, and how the tests read
// them.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/readers.h"
#include "chronomap/pipeline/session.h"
#include "test_support.h"

namespace chronomap {

#ifndef CHRONOMAP_SOURCE_DIR
#error "CHRONOMAP_SOURCE_DIR must name the project's source folder"
#endif
#ifndef CHRONOMAP_TEST_BAGS_DIR
#error "CHRONOMAP_TEST_BAGS_DIR must name the build folder of the shared test recordings"
#endif
#ifndef CHRONOMAP_ROS2_WRITER_DIR
#error "CHRONOMAP_ROS2_WRITER_DIR must name the build folder of the npm writer"
#endif

/// The recordings are made once per build by tests/ingest/ros/make_test_bags.sh (CTest runs it as the
/// fixture BagData before the bag tests; SetUpTestSuite runs it too, which costs nothing once
/// they exist, so that a suite run outside CTest finds them). `Suite::kWriters` names what its
/// bags need and `Suite::kErrorFile` where the script leaves that writer's failure: every test
/// of the suite then fails under CI=true and is skipped elsewhere. Scratch files go in dir_.
template <class Suite>
class BagFixture : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // The tests open bags through openDataset itself, as a program without the pipeline does.
    registerRosReaders();
    dir_ = new test::TempDir();
    const std::filesystem::path src = CHRONOMAP_SOURCE_DIR;
    const auto made = test::runCommand((src / "tests/ingest/ros/make_test_bags.sh").string() + " " + test::cli() + " " +
                                       src.string() + " " + CHRONOMAP_ROS2_WRITER_DIR + " " + recordings().string());
    if (made.exit_code != 0) {
      generator_error_ = "make_test_bags.sh: " + made.err;
    } else if (std::filesystem::exists(recordings() / Suite::kErrorFile)) {
      const auto bytes = test::bytesOf(recordings() / Suite::kErrorFile);
      generator_error_.assign(bytes.begin(), bytes.end());
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (generator_error_.empty()) return;
    if (test::underCi()) FAIL() << "writing the test bags failed: " << generator_error_;
    GTEST_SKIP() << "writing the test bags failed (" << Suite::kWriters << " missing?): " << generator_error_;
  }

  /// The shared recordings: the simulated session and the bags.
  static std::filesystem::path recordings() { return CHRONOMAP_TEST_BAGS_DIR; }
  static std::filesystem::path tum() { return recordings() / "sim" / "session_00"; }
  static std::filesystem::path bags() { return recordings() / "bags"; }
  static std::filesystem::path bag(const std::string& name) { return bags() / name; }

  /// The bags keep the TUM PNG's units (5000 per metre) in their 16UC1 images.
  static DatasetSettings bagSettings() {
    DatasetSettings s;
    s.depth_scale = 5000.0;
    return s;
  }
  static std::vector<uint8_t> mapBytes(const std::filesystem::path& path, const DatasetSettings& dataset) {
    SessionSettings s;
    s.dataset = dataset;
    s.integrator.threads = 2;
    return encodeSessionMap(integrateDataset(path, s).map, nlohmann::json::object());
  }

  static inline test::TempDir* dir_ = nullptr;
  static inline std::string generator_error_;
};

}  // namespace chronomap
