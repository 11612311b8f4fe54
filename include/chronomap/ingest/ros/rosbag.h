#pragma once
/// @file
/// ROS bags: what a bag holds. ROS 1 bags are read through librosbag, ROS 2 bags (MCAP or
/// SQLite storage, CDR messages) by chronomap's own readers. Bags are integrated through
/// openDataset (io/dataset.h, DatasetFormat::RosBag or Ros2Bag, BagSettings).

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace chronomap {

/// One topic of a bag.
struct BagTopic {
  std::string name;
  std::string type;  ///< e.g. "sensor_msgs/Image" (ROS 1), "sensor_msgs/msg/Image" (ROS 2)
  uint64_t messages = 0;
  std::string encoding;  ///< sensor_msgs/Image: the first message's encoding ("16UC1", "rgb8"); else empty
};

/// The topics of a ROS 1 or ROS 2 bag, by name. `note`, when given, receives what could not be
/// read (an MCAP file cut short: the counts are of what is intact), or is cleared.
/// @throw UsageError when the file does not exist; FormatError naming the file when it cannot be read.
std::vector<BagTopic> listBag(const std::filesystem::path& path, std::string* note = nullptr);

/// True when this build reads ROS 1 bags (it was built with librosbag).
bool rosBagSupported();

}  // namespace chronomap
