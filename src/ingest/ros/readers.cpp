#include "chronomap/ingest/ros/readers.h"

#include <mutex>

#include "chronomap/core/error.h"
#include "chronomap/ingest/registry.h"
#include "rosbag1.h"
#include "rosbag2.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

bool isRosBag1(const fs::path& path) {
  std::error_code ec;
  return !fs::is_directory(path, ec) && path.extension() == ".bag";
}

std::unique_ptr<Dataset> openRosBag1Checked(const fs::path& path, const DatasetSettings& settings) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw UsageError(path.string() + ": a ROS 1 bag is a file (.bag)");
  return openRosBag(path, settings);
}

}  // namespace

void registerRosReaders() {
  static std::once_flag once;
  std::call_once(once, [] {
    registerDatasetReader({"rosbag", {"bag"},
                           "ROS 1 bag (.bag): depth or cloud topic, colour, camera info, poses from /tf or a topic",
                           isRosBag1, openRosBag1Checked});
    registerDatasetReader({"ros2bag", {"mcap", "db3"},
                           "ROS 2 bag: .mcap or .db3 storage, or its folder with metadata.yaml; topics as for rosbag",
                           isRos2Bag, openRos2Bag});
  });
}

}  // namespace chronomap
