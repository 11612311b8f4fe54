#include "chronomap/pipeline/maps.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/export/export.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/render/colour.h"
#include "chronomap/render/top_view.h"
#include "json_vec.h"

namespace chronomap {

namespace fs = std::filesystem;

MapRef parseMapRef(const std::string& text) {
  const size_t at = text.rfind('@');
  if (at == std::string::npos || fs::exists(text)) return {text, std::nullopt};
  return {text.substr(0, at), parseTime(text.substr(at + 1))};
}

SessionMap loadSessionMap(const MapRef& ref, const CmapFile& file) {
  const std::string path = ref.path.string();
  if (file.header.kind == MapKind::Session) {
    if (ref.time_s) throw UsageError(path + " is a session map: it has no times to pick with @");
    return sessionMapFrom(file, path);
  }
  if (file.header.kind == MapKind::Temporal) {
    if (!ref.time_s) throw UsageError(path + " is a 4D map: say which time to compare, as " + path + "@TIME");
    return temporalMapFrom(file, path).snapshot(*ref.time_s);
  }
  throw UsageError(path + " holds a " + std::string(kindName(file.header.kind)) +
                   " map; diff compares session maps and 4D maps");
}

DiffMap diffMaps(const MapRef& a, const MapRef& b, const DiffSettings& settings, const TileCacheSettings& cache) {
  if (isTiledMapFolder(a.path) || isTiledMapFolder(b.path)) {
    if (!a.time_s || !b.time_s || !fs::exists(b.path) || !fs::equivalent(a.path, b.path)) {
      throw UsageError("a tiled map is compared with itself at two times: give DIR@TIME and DIR@TIME");
    }
    TiledMap map(a.path, cache);
    return map.diff(*a.time_s, *b.time_s, settings);
  }
  const CmapFile fa = readCmap(a.path);
  if (fa.header.kind == MapKind::Temporal && a.time_s && b.time_s && fs::exists(b.path) &&
      fs::equivalent(a.path, b.path)) {
    return diff(temporalMapFrom(fa, a.path.string()), *a.time_s, *b.time_s, settings);
  }
  const SessionMap ma = loadSessionMap(a, fa);
  const SessionMap mb = loadSessionMap(b, readCmap(b.path));
  return diff(ma, mb, settings);
}

Changes changesBetween(const MapRef& before, const MapRef& after, const ChangeSettings& settings,
                       const TileCacheSettings& cache) {
  settings.validate();
  return changesOf(diffMaps(before, after, settings.diff, cache), settings);
}

ColourDiffReport colourDiffMaps(const MapRef& before, const MapRef& after, const ColourDiffSettings& settings) {
  if (!before.time_s || !after.time_s || before.path != after.path) {
    throw UsageError("--colour compares two times of one 4D map: give A and B as MAP.cmap@TIME");
  }
  settings.validate();
  const TemporalMap map = readTemporalMap(before.path);
  ColourDiffReport r;
  if (settings.lighting_invariant) {
    const double later = std::max(*before.time_s, *after.time_s);
    r.model = fitColour(map, -std::numeric_limits<double>::infinity(), std::nextafter(later, -1e300));
  }
  r.diff = colourChanges(map, *before.time_s, *after.time_s, r.model ? &*r.model : nullptr, settings);
  return r;
}

SessionMap snapshotAt(const TemporalMap& map, double time_s, const std::string& name) {
  if (map.sessionCount() == 0 || time_s < map.sessions().front().time_s) {
    throw UsageError(name + " holds no session at or before " + formatTime(time_s) +
                     (map.sessionCount() ? " (the first is at " + formatTime(map.sessions().front().time_s) + ")" : ""));
  }
  return map.snapshot(time_s);
}

OneState stateOfMap(const fs::path& path, std::optional<double> time_s) {
  const CmapFile file = readCmap(path);
  const std::string name = path.string();
  if (file.header.kind == MapKind::Session) {
    if (time_s) throw UsageError(name + " is a session map: it has one time, so --at is not for it");
    return {sessionMapFrom(file, name), std::nullopt};
  }
  if (file.header.kind != MapKind::Temporal) {
    throw UsageError(name + " holds a " + std::string(kindName(file.header.kind)) +
                     " map; a session map or a 4D map is drawn");
  }
  const TemporalMap map = temporalMapFrom(file, name);
  if (map.sessionCount() == 0) throw UsageError(name + " is a 4D map with no session: nothing to draw");
  const double t = time_s ? *time_s : map.sessions().back().time_s;
  return {snapshotAt(map, t, name), t};
}

TemporalMap temporalMapOfFile(const fs::path& path) {
  const CmapFile file = readCmap(path);
  const std::string name = path.string();
  if (file.header.kind == MapKind::Temporal) return temporalMapFrom(file, name);
  if (file.header.kind != MapKind::Session) {
    throw UsageError(name + " holds a " + std::string(kindName(file.header.kind)) +
                     " map; the viewer opens a session map or a 4D map");
  }
  const SessionMap session = sessionMapFrom(file, name);
  const nlohmann::json meta = metadataOf(file);
  const double t = meta.contains("recorded_at") && meta["recorded_at"].is_number() ? meta["recorded_at"].get<double>() : 0.0;
  TemporalMap map(session.resolution_m());
  map.add(checkTime(t, name + ": recorded_at " + exactNumber(t)), session, AddSettings{false, path.filename().string()});
  return map;
}

size_t exportSessionMap(const fs::path& path, const SessionMap& map, const ExportSettings& settings) {
  const std::string ext = path.extension().string();
  if (ext == ".cmap") {
    writeSessionMap(path, map, settings.metadata);
    return map.leafCount();
  }
  if (ext == ".ply") return exportOccupiedPly(path, map);
  if (ext == ".ot") return exportOctomap(path, map);
  if (ext == ".png") {
    TopViewSettings view;
    view.pixels_per_voxel = settings.pixels_per_voxel;
    const ImageRgb img = renderTopView(map, view);
    writePng(path, img);
    return size_t{img.width} * img.height;
  }
  throw UsageError("output '" + path.string() + "' must end in .cmap, .ply, .ot or .png");
}

size_t writeChangeFrequencyPly(const fs::path& path, const TemporalMap& map, const ChangeFrequency& frequency,
                               uint32_t min_changes) {
  const uint32_t lo = min_changes, hi = frequency.max_count;
  PointCloud cloud;
  cloud.points.reserve(frequency.voxels.size());
  cloud.colours.reserve(frequency.voxels.size());
  for (const VoxelChangeCount& v : frequency.voxels) {
    cloud.points.push_back(map.grid().centerOf(v.key).cast<float>());
    const double t = hi > lo ? static_cast<double>(v.count - lo) / static_cast<double>(hi - lo) : 1.0;
    cloud.colours.push_back(heatColour(t));
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  writePly(path, cloud);
  return cloud.points.size();
}

namespace {

using pipeline_detail::vec3;

/// Removes the component files of an earlier segmentation into `folder` that this one did not
/// write (component_NNNN.cmap and .ply beyond its components), so the folder matches its index.
void removeStaleComponents(const fs::path& folder, const std::vector<fs::path>& written) {
  std::vector<fs::path> stale;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string stem = entry.path().stem().string();
    const std::string ext = entry.path().extension().string();
    const bool component = stem.size() == 14 && stem.rfind("component_", 0) == 0 && (ext == ".cmap" || ext == ".ply") &&
                           std::all_of(stem.begin() + 10, stem.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (!component || !entry.is_regular_file()) continue;
    if (std::find(written.begin(), written.end(), folder / entry.path().stem()) == written.end()) {
      stale.push_back(entry.path());
    }
  }
  for (const fs::path& p : stale) fs::remove(p);
}

}  // namespace

nlohmann::json segmentationJson(const Segmentation& segmentation, const SegmentSettings& settings) {
  nlohmann::json list = nlohmann::json::array();
  for (const Component& c : segmentation.components) {
    list.push_back({{"id", c.id},
                    {"voxels", c.voxels},
                    {"volume_m3", c.volume_m3},
                    {"bbox_min", vec3(c.bbox_min_m)},
                    {"bbox_max", vec3(c.bbox_max_m)},
                    {"centroid", vec3(c.centroid_m)},
                    {"mean_color", {c.mean_colour.r, c.mean_colour.g, c.mean_colour.b}},
                    {"kind", toString(c.kind)}});
  }
  return {{"components", list}, {"dropped", segmentation.dropped}, {"connectivity", toString(settings.connectivity)}};
}

void writeComponents(const fs::path& folder, const DiffMap& diff, const Segmentation& segmentation,
                     const std::string& source, const nlohmann::json& summary) {
  std::vector<fs::path> stems;  // folder/component_NNNN
  for (const Component& c : segmentation.components) {
    char name[32];
    std::snprintf(name, sizeof(name), "component_%04u", c.id);
    stems.push_back(folder / name);
  }
  // Every file this writes is checked against the input before the first is written.
  for (const fs::path& stem : stems) {
    refuseOverwritingInputs(stem.string() + ".cmap", {source});
    refuseOverwritingInputs(stem.string() + ".ply", {source});
  }
  refuseOverwritingInputs(folder / "components.json", {source});
  // All or nothing: the files go to a staging folder, moved into `folder` once all are written.
  StagedFolder staged(folder);
  for (size_t i = 0; i < stems.size(); ++i) {
    const Component& c = segmentation.components[i];
    const DiffMap part = componentDiff(diff, c);
    const std::string staged_stem = (staged.path() / stems[i].filename()).string();
    writeDiffMap(staged_stem + ".cmap", part,
                     {{"created_by", "chronomap segment"}, {"from", source}, {"component", c.id}});
    exportDiffPly(staged_stem + ".ply", part, part.cells());
  }
  const std::string index = summary.dump(2) + "\n";
  writeFileAtomic(staged.path() / "components.json", std::vector<uint8_t>(index.begin(), index.end()));
  staged.commit();
  removeStaleComponents(folder, stems);
}

}  // namespace chronomap
