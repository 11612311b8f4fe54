#include "chronomap/store/diff_file.h"

#include <cstring>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"

namespace chronomap {

namespace {

// One cell on disk: x, y, z (uint16 each), level, kind, r, g, b (uint8 each), value (float32),
// little endian, no padding: 15 bytes.
constexpr size_t kCellBytes = 15;

void put16(std::vector<uint8_t>& out, uint16_t v) {
  out.push_back(static_cast<uint8_t>(v & 0xff));
  out.push_back(static_cast<uint8_t>(v >> 8));
}

uint16_t get16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

/// The diff's file with `extra` (a JSON object) added to its metadata.
void writeDiffFile(const std::filesystem::path& path, const DiffMap& diff, const nlohmann::json& meta,
                   const nlohmann::json& extra) {
  CmapHeader header;
  header.kind = MapKind::Diff;
  header.resolution_m = diff.resolution_m();
  bool any = false;
  std::vector<uint8_t> cells;
  cells.reserve(diff.cells().size() * kCellBytes);
  for (const ChangeCell& c : diff.cells()) {
    const Eigen::Vector3d a = diff.grid().cornerOf(c.key);
    const Eigen::Vector3d b = a + Eigen::Vector3d::Constant(diff.resolution_m() * (1 << c.level));
    header.bounds_min_m = any ? header.bounds_min_m.cwiseMin(a) : a;
    header.bounds_max_m = any ? header.bounds_max_m.cwiseMax(b) : b;
    any = true;
    put16(cells, c.key.x);
    put16(cells, c.key.y);
    put16(cells, c.key.z);
    cells.insert(cells.end(), {c.level, static_cast<uint8_t>(c.kind), c.colour.r, c.colour.g, c.colour.b});
    uint8_t value[4];
    std::memcpy(value, &c.value, 4);
    cells.insert(cells.end(), value, value + 4);
  }
  nlohmann::json j = nlohmann::json::object();
  j["user"] = meta.is_object() ? meta : nlohmann::json::object();
  j["mode"] = toString(diff.settings().mode);
  j["alpha"] = diff.settings().effectiveAlpha();
  j["neighbourhood_voxels"] = diff.settings().neighbourhood_voxels;
  j["min_shift_voxels"] = diff.settings().min_shift_voxels;
  j["shift_plane_ratio"] = diff.settings().shift_plane_ratio;
  j["kept_surface_radius_voxels"] = diff.settings().kept_surface_radius_voxels;
  j["kept_surface_share"] = diff.settings().kept_surface_share;
  j["dark_surface_radius_voxels"] = diff.settings().dark_surface_radius_voxels;
  j["dark_surface_brightness"] = diff.settings().dark_surface_brightness;
  j["dark_surface_contrast"] = diff.settings().dark_surface_contrast;
  j["dark_surface_share"] = diff.settings().dark_surface_share;
  j["seen_at_both"] = diff.settings().seen_at_both;
  if (extra.is_object()) j.update(extra);
  const std::string text = j.dump();
  std::vector<CmapBlock> blocks(2);
  blocks[0] = {"META", std::vector<uint8_t>(text.begin(), text.end())};
  blocks[1] = {"CELL", std::move(cells)};
  writeFileAtomic(path, encodeCmap(header, blocks));
}

}  // namespace

void writeDiffMap(const std::filesystem::path& path, const DiffMap& diff, const nlohmann::json& meta) {
  writeDiffFile(path, diff, meta, nullptr);
}

void writeDiffMap(const std::filesystem::path& path, const Changes& changes, const ChangeSettings& settings,
                  const std::string& preset, const nlohmann::json& meta) {
  nlohmann::json record{{"preset", preset},
                        {"settings", changeSettingsJson(settings)},
                        {"objects", changedObjectsJson(changes.objects)}};
  writeDiffFile(path, changes.diff, meta, {{"changes", std::move(record)}});
}

nlohmann::json diffChangesOf(const CmapFile& file, const std::string& source) {
  if (file.header.kind != MapKind::Diff) {
    throw FormatError(source + ": holds a " + std::string(kindName(file.header.kind)) + " map, not a diff");
  }
  const nlohmann::json j = metadataOf(file);
  return j.is_object() && j.contains("changes") ? j["changes"] : nlohmann::json();
}

DiffMap diffMapFrom(const CmapFile& file, const std::string& source) {
  if (file.header.kind != MapKind::Diff) {
    throw FormatError(source + ": holds a " + std::string(kindName(file.header.kind)) + " map, not a diff");
  }
  DiffSettings settings;
  try {
    const nlohmann::json j = metadataOf(file);
    settings.mode = parseDiffMode(j.at("mode").get<std::string>());
    settings.alpha = j.at("alpha").get<double>();
    settings.neighbourhood_voxels = j.value("neighbourhood_voxels", 0);
    settings.min_shift_voxels = j.value("min_shift_voxels", 0.0);
    settings.shift_plane_ratio = j.value("shift_plane_ratio", 0.0);
    settings.kept_surface_radius_voxels = j.value("kept_surface_radius_voxels", 0);
    settings.kept_surface_share = j.value("kept_surface_share", DiffSettings::kDefaultKeptSurfaceShare);
    settings.dark_surface_radius_voxels = j.value("dark_surface_radius_voxels", 0);
    settings.dark_surface_brightness = j.value("dark_surface_brightness", DiffSettings::kDefaultDarkSurfaceBrightness);
    settings.dark_surface_contrast = j.value("dark_surface_contrast", DiffSettings::kDefaultDarkSurfaceContrast);
    settings.dark_surface_share = j.value("dark_surface_share", DiffSettings::kDefaultDarkSurfaceShare);
    settings.seen_at_both = j.value("seen_at_both", false);
    settings.validate();
  } catch (const std::exception& e) {
    throw FormatError(source + ": invalid diff settings (" + e.what() + ")");
  }
  const CmapBlock& block = file.block("CELL", source);
  if (block.data.size() % kCellBytes != 0) throw FormatError(source + ": block CELL has an impossible size");
  std::vector<ChangeCell> cells(block.data.size() / kCellBytes);
  const uint8_t* p = block.data.data();
  for (ChangeCell& c : cells) {
    c.key = VoxelKey{get16(p), get16(p + 2), get16(p + 4)};
    c.level = p[6];
    c.kind = static_cast<ChangeKind>(p[7]);
    c.colour = Rgb{p[8], p[9], p[10]};
    std::memcpy(&c.value, p + 11, 4);
    p += kCellBytes;
  }
  try {
    return DiffMap::fromCells(file.header.resolution_m, settings, std::move(cells));
  } catch (const Error& e) {
    throw FormatError(source + ": " + e.what());
  }
}

DiffMap readDiffMap(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return diffMapFrom(readCmap(path), path.string()); });
}

}  // namespace chronomap
