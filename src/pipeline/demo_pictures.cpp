#include "demo_pictures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "chronomap/render/change_view.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

constexpr int kPixelsPerVoxel = 3;        // the pair's top view, as the demo's other top views
constexpr int kCloseUpSide_px = 600;      // a close-up's map at most about this wide
constexpr int kCloseUpMaxPixelsPerVoxel = 8;

/// Pixels a voxel for a close-up of `object`: as many as keep its window near kCloseUpSide_px.
int closeUpScale(const ChangedObject& object, const Changes& changes, double margin_m) {
  Eigen::Vector2d lo = object.bbox_min_m.head<2>(), hi = object.bbox_max_m.head<2>();
  if (object.kind == ObjectChange::Moved) {
    lo = lo.cwiseMin((object.from.centroid_m - object.from.size_m / 2).head<2>());
    hi = hi.cwiseMax((object.from.centroid_m + object.from.size_m / 2).head<2>());
  }
  const double side_m = (hi - lo).maxCoeff() + 2 * margin_m;
  const double voxels = std::max(1.0, side_m / changes.diff.resolution_m());
  return std::clamp(static_cast<int>(kCloseUpSide_px / voxels), 1, kCloseUpMaxPixelsPerVoxel);
}

}  // namespace

std::vector<Room> readRooms(const fs::path& scene_json) {
  const std::string source = scene_json.string();
  std::vector<Room> rooms;
  try {
    const nlohmann::json j = nlohmann::json::parse(readTextFile(scene_json));
    if (!j.contains("rooms")) return rooms;
    for (const auto& r : j.at("rooms")) {
      Room room;
      room.name = r.at("name").get<std::string>();
      const Eigen::Vector2d lo(r.at("min").at(0).get<double>(), r.at("min").at(1).get<double>());
      const Eigen::Vector2d hi(r.at("max").at(0).get<double>(), r.at("max").at(1).get<double>());
      if (!lo.allFinite() || !hi.allFinite() || (hi.array() < lo.array()).any()) {
        throw FormatError("room '" + room.name + "' has no area (min above max)");
      }
      room.area = Eigen::AlignedBox2d(lo, hi);
      rooms.push_back(std::move(room));
    }
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(source + ": not a simulator scene (" + e.what() + ")");
  } catch (const FormatError& e) {
    throw FormatError(source + ": " + e.what());
  }
  return rooms;
}

std::vector<MapArea> roomAreas(const std::vector<Room>& rooms) {
  std::vector<MapArea> areas;
  for (const Room& r : rooms) areas.push_back({r.name, r.area});
  return areas;
}

std::vector<std::string> drawChangePictures(const fs::path& images, const std::string& stem,
                                            const SessionMap& background, const Changes& changes,
                                            const std::vector<Room>& rooms) {
  ChangeViewSettings settings;
  settings.view.pixels_per_voxel = kPixelsPerVoxel;
  settings.view.areas = roomAreas(rooms);
  std::vector<std::string> names = {stem + ".png"};
  writePng(images / names.back(), drawChanges(background, changes, settings).image);
  for (const ChangedObject& o : changes.objects) {
    char suffix[32];
    std::snprintf(suffix, sizeof suffix, "_object_%02u.png", static_cast<unsigned>(o.id));
    settings.view.pixels_per_voxel = closeUpScale(o, changes, settings.close_up_margin_m);
    names.push_back(stem + suffix);
    writePng(images / names.back(), drawObjectCloseUp(background, changes, o, settings).image);
  }
  return names;
}

void drawMapPicture(const fs::path& path, const SessionMap& map, const std::vector<Room>& rooms) {
  TopViewSettings settings;
  settings.pixels_per_voxel = kPixelsPerVoxel;
  settings.areas = roomAreas(rooms);
  writePng(path, drawTopView(map, settings).image);
}

}  // namespace chronomap
