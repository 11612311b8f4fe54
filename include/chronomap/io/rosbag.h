#pragma once
/// @file
/// ROS 1 bags (read through librosbag): what a bag holds. Bags are integrated through
/// openDataset (io/dataset.h, DatasetFormat::RosBag, BagSettings).

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace chronomap::io {

/// One topic of a bag.
struct BagTopic {
  std::string name;
  std::string type;  ///< e.g. "sensor_msgs/Image"
  uint64_t messages = 0;
  std::string encoding;  ///< sensor_msgs/Image: the first message's encoding ("16UC1", "rgb8"); else empty
};

/// The topics of a bag, by name. @throw UsageError when the file does not exist; FormatError
/// naming the file when librosbag cannot read it.
std::vector<BagTopic> listBag(const std::filesystem::path& path);

/// True when this build reads ROS 1 bags (it was built with librosbag).
bool rosBagSupported();

}  // namespace chronomap::io
