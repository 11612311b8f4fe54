#pragma once
/// @file
/// A costmap as ROS map_server files: a YAML description and a PGM image.

#include <filesystem>

#include "chronomap/analysis/costmap.h"

namespace chronomap {

/// Writes `costmap` as `yaml_path` (image, resolution, origin, thresholds, mode: raw) and a PGM
/// of the same stem beside it (each pixel's grey level its cost, 0 free .. 100 lethal, 255
/// unknown; the first row is the highest y), each atomically: ROS map_server and nav2_map_server
/// load it as the same grid, -1 unknown and every cost as it is. @return the PGM's path.
/// @throw IoError.
std::filesystem::path writeMapServer(const std::filesystem::path& yaml_path, const Costmap& costmap);

}  // namespace chronomap
