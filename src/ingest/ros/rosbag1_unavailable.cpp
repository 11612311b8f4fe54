// Built without librosbag (CHRONOMAP_ROSBAG=OFF): bags are refused with the reason.

#include "chronomap/core/error.h"
#include "chronomap/ingest/ros/rosbag.h"
#include "rosbag1.h"

namespace chronomap {

namespace {

[[noreturn]] void refuse(const std::filesystem::path& path) {
  throw UsageError(path.string() + ": this chronomap was built without ROS 1 bag support (CHRONOMAP_ROSBAG=OFF)");
}

}  // namespace

std::unique_ptr<Dataset> openRosBag(const std::filesystem::path& path, const DatasetSettings&) { refuse(path); }
std::vector<BagTopic> listRosBag1(const std::filesystem::path& path) { refuse(path); }
bool rosBagSupported() { return false; }

}  // namespace chronomap
