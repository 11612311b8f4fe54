#pragma once
// The ROS 2 bag reader behind openDataset (internal): MCAP (mcap.h) or SQLite (.db3) storage,
// CDR messages (cdr.h), and the frames made by bag_dataset.h as for ROS 1 bags.

#include <filesystem>
#include <memory>
#include <vector>

#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/rosbag.h"

namespace chronomap {

/// True for a ROS 2 bag: a folder with metadata.yaml, a .mcap or .db3 file, or a file that
/// starts with MCAP's or SQLite's magic.
bool isRos2Bag(const std::filesystem::path& path);

/// @throw UsageError for topics that do not fit or a folder without one storage file;
/// DataError / FormatError naming the file.
std::unique_ptr<Dataset> openRos2Bag(const std::filesystem::path& path, const DatasetSettings& settings);

/// The topics of a ROS 2 bag, with their ROS 2 type names ("sensor_msgs/msg/Image").
std::vector<BagTopic> listRos2Bag(const std::filesystem::path& path, std::string* note = nullptr);

}  // namespace chronomap
