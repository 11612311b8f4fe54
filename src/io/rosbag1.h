#pragma once
// The ROS 1 bag reader behind openDataset; librosbag's headers stay in rosbag1.cpp.

#include <filesystem>
#include <memory>

#include "chronomap/io/dataset.h"

namespace chronomap::io {

/// @throw UsageError for topics that do not fit, DataError / FormatError naming the bag.
std::unique_ptr<Dataset> openRosBag(const std::filesystem::path& path, const DatasetSettings& settings);

}  // namespace chronomap::io
