// What the viewer draws: snapshots with a level of detail, diffs with objects, histories.

#include "chronomap/view/scene.h"

#include <algorithm>
#include <limits>

#include "chronomap/analysis/change_preset.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "lod.h"

namespace chronomap {

namespace {

// One occupied list of the snapshot, in the map's (Morton) walk order.
struct Occupied {
  uint64_t code = 0;
  VoxelKey key;
  uint8_t level = 0;
  Rgb colour;
  uint8_t changes = 0;
  uint16_t since = 0;
};

bool cubeMeetsRegion(const VoxelKey& corner, int level, const std::array<VoxelKey, 2>& region) {
  const uint32_t span = (1u << level) - 1u;
  auto meets = [span](uint16_t c, uint16_t lo, uint16_t hi) { return c <= hi && c + span >= lo; };
  return meets(corner.x, region[0].x, region[1].x) && meets(corner.y, region[0].y, region[1].y) &&
         meets(corner.z, region[0].z, region[1].z);
}

std::vector<Occupied> occupiedAt(const TemporalMap& map, uint32_t rank, const SnapshotRequest& request) {
  std::vector<Occupied> out;
  map.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
    if (request.region && !cubeMeetsRegion(corner, level, *request.region)) return;
    // The entry valid at `rank`: the last one of a session at or before it.
    const auto it = std::upper_bound(entries.begin(), entries.end(), rank,
                                     [](uint32_t r, const TemporalMap::Entry& e) { return r < e.session; });
    if (it == entries.begin()) return;
    const auto& valid = *(it - 1);
    if (valid.value.state() != VoxelState::Occupied) return;
    const auto index = static_cast<size_t>(it - entries.begin()) - 1;  // changes before and at `rank`
    out.push_back(Occupied{mortonEncode(corner), corner, static_cast<uint8_t>(level), valid.value.meanColour(),
                           static_cast<uint8_t>(std::min<size_t>(index, 255)),
                           static_cast<uint16_t>(std::min<uint32_t>(valid.session, 0xffff))});
  });
  return out;
}

}  // namespace

VoxelSet snapshotVoxels(const TemporalMap& map, const SnapshotRequest& request) {
  if (request.max_voxels == 0) throw UsageError("the voxel budget must be at least 1");
  if (request.min_level < 0 || request.min_level > kMaxLevel) {
    throw UsageError("the level of detail must lie in 0.." + std::to_string(kMaxLevel));
  }
  VoxelSet out;
  out.rank = map.rankAtOrBefore(request.time_s);
  if (!out.rank) {
    out.level = request.min_level;
    return out;
  }
  const auto items = occupiedAt(map, *out.rank, request);
  out.level = lod::chooseLevel(items, request.min_level, request.max_voxels);

  struct Sum {
    uint64_t id = 0;
    VoxelKey corner;
    uint8_t level = 0;
    uint64_t r = 0, g = 0, b = 0, members = 0;
    uint8_t changes = 0;
    uint16_t since = 0;
  };
  std::optional<Sum> open;
  auto flush = [&] {
    if (!open) return;
    const Sum& s = *open;
    out.keys.push_back(s.corner);
    out.levels.push_back(s.level);
    const auto mean = [&](uint64_t sum) { return static_cast<uint8_t>((sum + s.members / 2) / s.members); };
    out.colours.push_back(Rgb{mean(s.r), mean(s.g), mean(s.b)});
    out.changes.push_back(s.changes);
    out.since.push_back(s.since);
    out.members.push_back(static_cast<uint32_t>(std::min<uint64_t>(s.members, std::numeric_limits<uint32_t>::max())));
    out.occupied_voxels += s.members;
  };
  for (const auto& o : items) {
    const uint64_t id = lod::cellId(o.code, o.level, out.level);
    if (!open || open->id != id) {
      flush();
      const int level = std::max<int>(out.level, o.level);
      open = Sum{id, cellCorner(o.key, level), static_cast<uint8_t>(level)};
    }
    Sum& s = *open;
    const uint64_t n = lod::unitVoxels(o.level);
    s.r += o.colour.r * n;
    s.g += o.colour.g * n;
    s.b += o.colour.b * n;
    s.members += n;
    s.changes = std::max(s.changes, o.changes);
    s.since = std::max(s.since, o.since);
  }
  flush();
  return out;
}

DiffRequest changeSettings() {
  const ChangeSettings preset = recommendedChangeSettings();
  DiffRequest r;
  r.diff = preset.diff;
  r.segment = preset.segment;
  return r;
}

DiffObjects diffObjects(const TemporalMap& map, const DiffRequest& request) {
  DiffObjects out{diff(map, request.t0_s, request.t1_s, request.diff), {}, {}};
  out.segmentation = segment(out.diff, request.segment);
  out.component_of_cell.assign(out.diff.cells().size(), 0);
  for (const auto& c : out.segmentation.components) {
    for (const uint32_t cell : c.cells) out.component_of_cell[cell] = c.id;
  }
  return out;
}

nlohmann::json componentJson(const Component& c) {
  auto vec = [](const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  return {{"id", c.id},
          {"kind", toString(c.kind)},
          {"voxels", c.voxels},
          {"volume_m3", c.volume_m3},
          {"bbox_min_m", vec(c.bbox_min_m)},
          {"bbox_max_m", vec(c.bbox_max_m)},
          {"centroid_m", vec(c.centroid_m)},
          {"color", {c.mean_colour.r, c.mean_colour.g, c.mean_colour.b}}};
}

nlohmann::json historyJson(const TemporalMap& map, const VoxelKey& corner, int level) {
  if (level < 0 || level > kMaxHistoryLevel) {
    throw UsageError("the history level must lie in 0.." + std::to_string(kMaxHistoryLevel));
  }
  const auto mask = static_cast<uint16_t>((1u << level) - 1u);
  if ((corner.x & mask) || (corner.y & mask) || (corner.z & mask)) {
    throw UsageError("the corner of a cube at level " + std::to_string(level) + " must be a multiple of " +
                     std::to_string(1 << level));
  }
  VoxelKey key = corner;
  std::vector<HistoryEntry> best = map.history(corner);
  if (level > 0) {
    bool best_occupied = false;
    const int n = 1 << level;
    for (int i = 0; i < n * n * n; ++i) {
      const auto k = offsetKey(corner, i % n, (i / n) % n, i / (n * n));
      if (!k) continue;
      auto h = map.history(*k);
      const bool occupied = std::any_of(h.begin(), h.end(),
                                        [](const HistoryEntry& e) { return e.counters.state() == VoxelState::Occupied; });
      if (occupied && (!best_occupied || h.size() > best.size())) {
        best = std::move(h);
        best_occupied = true;
        key = *k;
      }
    }
  }
  nlohmann::json entries = nlohmann::json::array();
  for (const auto& e : best) {
    const Rgb c = e.counters.meanColour();
    entries.push_back({{"time_s", e.time_s},
                       {"time", formatTime(e.time_s)},
                       {"session", map.rankAtOrBefore(e.time_s).value_or(0)},
                       {"state", toString(e.counters.state())},
                       {"probability", e.counters.probability()},
                       {"hits", e.counters.hits},
                       {"color", {c.r, c.g, c.b}},
                       {"level", e.level}});
  }
  const Eigen::Vector3d center = map.grid().centerOf(key);
  return {{"key", {key.x, key.y, key.z}},
          {"center_m", {center.x(), center.y(), center.z()}},
          {"entries", std::move(entries)}};
}

nlohmann::json mapInfoJson(const TemporalMap& map, const std::string& name) {
  nlohmann::json sessions = nlohmann::json::array();
  for (size_t i = 0; i < map.sessions().size(); ++i) {
    const auto& s = map.sessions()[i];
    sessions.push_back({{"rank", i}, {"time_s", s.time_s}, {"time", formatTime(s.time_s)}, {"name", s.name}});
  }
  const auto counts = map.counts();
  return {{"name", name},
          {"resolution_m", map.resolution_m()},
          {"key_origin", kKeyOrigin},
          {"sessions", std::move(sessions)},
          {"nodes", counts.nodes()},
          {"max_level", kMaxLevel},
          {"max_history_level", kMaxHistoryLevel}};
}

}  // namespace chronomap
