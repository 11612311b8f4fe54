// The self-contained tour: every voxel ever occupied with its state per session, and the
// objects that changed between sessions, inside one HTML file.

#include "chronomap/view/tour.h"

#include <algorithm>

#include "chronomap/analysis/changes.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/view/api.h"
#include "chronomap/view/packet.h"
#include "chronomap/view/scene.h"
#include "lod.h"

namespace chronomap {

namespace {

// One list that was occupied in some session; its states live in a shared buffer.
struct Item {
  uint64_t code = 0;
  VoxelKey key;
  uint8_t level = 0;
  Rgb colour;
  uint8_t changes = 0;
};

struct Timeline {
  std::vector<Item> items;
  std::vector<uint8_t> states;  // items.size() x stride, 2 bits per session
  size_t stride = 0;
  std::vector<uint64_t> occupied_voxels;  // per session
};

Timeline everOccupied(const TemporalMap& map) {
  const size_t sessions = map.sessionCount();
  Timeline t;
  t.stride = (sessions + 3) / 4;
  t.occupied_voxels.assign(sessions, 0);
  std::vector<uint8_t> row(t.stride);
  map.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
    std::fill(row.begin(), row.end(), 0);
    bool ever = false;
    Rgb colour;
    size_t next = 0;
    VoxelState state = VoxelState::Unknown;
    for (uint32_t s = 0; s < sessions; ++s) {
      for (; next < entries.size() && entries[next].session <= s; ++next) {
        state = entries[next].value.state();
        if (state == VoxelState::Occupied) colour = entries[next].value.meanColour();
      }
      row[s / 4] = static_cast<uint8_t>(row[s / 4] | static_cast<uint8_t>(state) << (2 * (s % 4)));
      if (state == VoxelState::Occupied) {
        ever = true;
        t.occupied_voxels[s] += lod::unitVoxels(level);
      }
    }
    if (!ever) return;
    t.items.push_back(Item{mortonEncode(corner), corner, static_cast<uint8_t>(level), colour,
                           static_cast<uint8_t>(std::min<size_t>(entries.size() - 1, 255))});
    t.states.insert(t.states.end(), row.begin(), row.end());
  });
  return t;
}

// The cells of the timeline at level of detail `level`, added to `w`; returns their number.
size_t addCells(PacketWriter& w, const Timeline& t, int level, size_t sessions) {
  std::vector<uint16_t> keys;
  std::vector<uint8_t> levels, colours, changes, states;
  std::vector<uint64_t> sums;  // r, g, b, voxels of the open cell
  uint64_t open = ~uint64_t{0};
  auto flush = [&] {
    if (open == ~uint64_t{0}) return;
    for (int c = 0; c < 3; ++c) colours.push_back(static_cast<uint8_t>((sums[c] + sums[3] / 2) / sums[3]));
  };
  for (size_t i = 0; i < t.items.size(); ++i) {
    const Item& o = t.items[i];
    const uint64_t id = lod::cellId(o.code, o.level, level);
    if (id != open) {
      flush();
      open = id;
      const int l = std::max<int>(level, o.level);
      const VoxelKey k = cellCorner(o.key, l);
      keys.insert(keys.end(), {k.x, k.y, k.z});
      levels.push_back(static_cast<uint8_t>(l));
      changes.push_back(0);
      states.insert(states.end(), t.stride, 0);
      sums.assign(4, 0);
    }
    const uint64_t n = lod::unitVoxels(o.level);
    sums[0] += o.colour.r * n;
    sums[1] += o.colour.g * n;
    sums[2] += o.colour.b * n;
    sums[3] += n;
    changes.back() = std::max(changes.back(), o.changes);
    // A cell's state per session is its most occupied member's (occupied > free > unknown).
    uint8_t* row = states.data() + states.size() - t.stride;
    for (size_t s = 0; s < sessions; ++s) {
      const int shift = 2 * static_cast<int>(s % 4);
      const int mine = (row[s / 4] >> shift) & 3, theirs = (t.states[i * t.stride + s / 4] >> shift) & 3;
      if (theirs > mine) row[s / 4] = static_cast<uint8_t>((row[s / 4] & ~(3 << shift)) | theirs << shift);
    }
  }
  flush();
  w.add("keys", std::span<const uint16_t>(keys));
  w.add("levels", std::span<const uint8_t>(levels));
  w.add("colors", std::span<const uint8_t>(colours));
  w.add("changes", std::span<const uint8_t>(changes));
  w.add("states", std::span<const uint8_t>(states));
  return levels.size();
}

nlohmann::json addDiffs(PacketWriter& w, const TemporalMap& map, const TourSettings& settings) {
  const auto& sessions = map.sessions();
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (uint32_t s = 0; s + 1 < sessions.size(); ++s) pairs.emplace_back(s, s + 1);
  if (sessions.size() > 2) pairs.emplace_back(0, static_cast<uint32_t>(sessions.size() - 1));
  std::vector<uint16_t> keys;
  std::vector<uint8_t> levels, kinds;
  std::vector<uint32_t> component;
  nlohmann::json diffs = nlohmann::json::array();
  // The objects of the one call (findChanges), as /api/diff?format=json lists them.
  ChangeSettings change_settings = recommendedChangeSettings();
  change_settings.diff = settings.diff;
  change_settings.segment = settings.segment;
  for (const auto& [from, to] : pairs) {
    const Changes o = findChanges(map, sessions[from].time_s, sessions[to].time_s, change_settings);
    const auto cells = o.diff.cells();
    const size_t sent = std::min(cells.size(), settings.max_diff_cells);
    std::vector<uint32_t> component_of_cell(sent, 0);
    nlohmann::json components = nlohmann::json::array();
    for (const auto& c : o.segmentation.components) {
      components.push_back(componentJson(c));
      for (const uint32_t cell : c.cells) {
        if (cell < sent) component_of_cell[cell] = c.id;
      }
    }
    diffs.push_back({{"from", from}, {"to", to}, {"first", levels.size()}, {"count", sent}, {"cells", cells.size()},
                     {"voxels", o.diff.voxelCount()}, {"components", std::move(components)},
                     {"objects", changedObjectsJson(o.objects)}, {"appeared_voxels", o.appeared_voxels},
                     {"vanished_voxels", o.vanished_voxels}, {"dropped", o.segmentation.dropped}});
    for (size_t i = 0; i < sent; ++i) {
      keys.insert(keys.end(), {cells[i].key.x, cells[i].key.y, cells[i].key.z});
      levels.push_back(cells[i].level);
      kinds.push_back(static_cast<uint8_t>(cells[i].kind));
      component.push_back(component_of_cell[i]);
    }
  }
  w.add("diff_keys", std::span<const uint16_t>(keys));
  w.add("diff_levels", std::span<const uint8_t>(levels));
  w.add("diff_kinds", std::span<const uint8_t>(kinds));
  w.add("diff_component", std::span<const uint32_t>(component));
  return diffs;
}

}  // namespace

std::string tourData(const TemporalMap& map, const std::string& name, const TourSettings& settings, TourReport* report) {
  if (map.sessionCount() == 0) throw UsageError("the map holds no session");
  if (settings.max_voxels == 0) throw UsageError("the voxel budget must be at least 1");
  const Timeline timeline = everOccupied(map);
  const int level = lod::chooseLevel(timeline.items, 0, settings.max_voxels);
  PacketWriter w;
  const size_t cells = addCells(w, timeline, level, map.sessionCount());
  const auto tooLarge = [&](size_t bytes, const std::string& what) {
    std::string m = "a tour of this map would hold ";
    m.append(std::to_string(bytes)).append(" bytes of ").append(what).append(", more than its budget of ");
    m.append(std::to_string(settings.max_bytes)).append(" (fewer cells with --max-voxels or --max-diff-cells; ");
    m.append("chronomap view serves any map)");
    throw UsageError(m);
  };
  // The cells' bytes are known before the diffs, which take most of the time: refuse early.
  const size_t cell_bytes = cells * (11 + (map.sessionCount() + 3) / 4);
  if (cell_bytes > settings.max_bytes) tooLarge(cell_bytes, "voxel timeline");
  nlohmann::json diffs = addDiffs(w, map, settings);
  size_t diff_cells = 0;
  for (const auto& d : diffs) diff_cells += d["count"].get<size_t>();
  if (cell_bytes + 12 * diff_cells > settings.max_bytes) tooLarge(cell_bytes + 12 * diff_cells, "voxels and diffs");
  if (report) {
    report->cells = cells;
    report->level = level;
    report->diffs = diffs.size();
    report->diff_cells = diff_cells;
    report->occupied_voxels = timeline.occupied_voxels;
  }
  return w.finish({{"map", mapInfoJson(map, name)},
                   {"level", level},
                   {"cells", cells},
                   {"occupied_voxels", timeline.occupied_voxels},
                   {"diffs", std::move(diffs)}});
}

TourReport writeTour(const std::filesystem::path& path, const TemporalMap& map, const std::string& name,
                     const TourSettings& settings) {
  TourReport report;
  const std::string html = selfContainedPage(tourData(map, name, settings, &report));
  writeFileAtomic(path, std::vector<uint8_t>(html.begin(), html.end()));
  report.bytes = html.size();
  return report;
}

}  // namespace chronomap
