#pragma once
/// @file
/// A costmap as ROS map_server files: a YAML description and a PGM image.

#include <filesystem>

#include "chronomap/analysis/costmap.h"

namespace chronomap {

/// Writes `costmap` as `yaml_path` (image, resolution, origin, thresholds, mode: scale) and a PGM
/// of the same stem beside it (254 free .. 0 lethal in proportion to the cost, 205 unknown; the
/// first row is the highest y), each atomically. @return the PGM's path. @throw IoError.
std::filesystem::path writeMapServer(const std::filesystem::path& yaml_path, const Costmap& costmap);

}  // namespace chronomap
