#pragma once
// Foxglove's JSON schemas as @foxglove/schemas publishes them (src/export/foxglove.*.json,
// written by tests/export/foxglove/write_schemas.mjs), built into the library by
// cmake/EmbedFiles.cmake.

#include <string_view>

namespace chronomap::foxglove_schemas {

std::string_view frameTransform();  ///< foxglove.FrameTransform
std::string_view pointCloud();      ///< foxglove.PointCloud
std::string_view sceneUpdate();     ///< foxglove.SceneUpdate
std::string_view grid();            ///< foxglove.Grid

}  // namespace chronomap::foxglove_schemas
