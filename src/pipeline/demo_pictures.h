#pragma once
// The demo report's pictures of the changes between two sessions (pipeline/demo.h runs the demo):
// the pair's top view and a close-up per object, with axes in metres, a scale bar, the rooms'
// names and a legend.

#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/analysis/changes.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/render/top_view.h"
#include "chronomap/sim/scene.h"

namespace chronomap {

/// The rooms of a simulation's scene.json ("rooms": name, min and max corner in metres); the
/// rest of each Room stays at its defaults. A scene without rooms gives none.
/// @throw IoError, FormatError naming the file.
std::vector<Room> readRooms(const std::filesystem::path& scene_json);

/// The rooms as areas to name on a top view.
std::vector<MapArea> roomAreas(const std::vector<Room>& rooms);

/// Writes `images`/STEM.png (`background` from above with every object of `changes`:
/// drawChanges, 3 pixels a voxel) and `images`/STEM_object_NN.png per object (NN its id, two
/// digits at least: drawObjectCloseUp, about 600 pixels across at most), each with the rooms'
/// names; returns the file names written, the top view first.
/// @throw DataError when the background is empty; IoError when a file cannot be written.
std::vector<std::string> drawChangePictures(const std::filesystem::path& images, const std::string& stem,
                                            const SessionMap& background, const Changes& changes,
                                            const std::vector<Room>& rooms);

/// Writes `path` (a .png): `map` from above with axes, a scale bar, the rooms' names and a legend,
/// 3 pixels a voxel.
void drawMapPicture(const std::filesystem::path& path, const SessionMap& map, const std::vector<Room>& rooms);

}  // namespace chronomap
