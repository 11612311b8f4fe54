#include "chronomap/temporal/tiles.h"

#include <algorithm>
#include <map>
#include <string>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

using Parts = TemporalMap::Parts;
using Ref = TemporalMap::Ref;
constexpr Ref kEmpty = TemporalMap::kEmpty;
constexpr Ref kListBit = TemporalMap::kListBit;

std::string tileName(const TileKey& t) {
  return "tile (" + std::to_string(t.x) + ", " + std::to_string(t.y) + ", " + std::to_string(t.z) + ")";
}

/// Copies nodes and lists of one Parts into another, keeping the source's list offsets.
class PartsCopier {
 public:
  explicit PartsCopier(const Parts& src) : src_(src), offsets_(src.list_sizes.size() + 1, 0) {
    for (size_t i = 0; i < src.list_sizes.size(); ++i) offsets_[i + 1] = offsets_[i] + src.list_sizes[i];
  }
  const Parts& source() const { return src_; }

  Ref copyList(Parts& out, Ref r) const {
    const uint32_t i = r & ~kListBit;
    const Ref mine = static_cast<Ref>(out.list_sizes.size()) | kListBit;
    out.list_sizes.push_back(src_.list_sizes[i]);
    out.entries.insert(out.entries.end(), src_.entries.begin() + static_cast<std::ptrdiff_t>(offsets_[i]),
                       src_.entries.begin() + static_cast<std::ptrdiff_t>(offsets_[i + 1]));
    return mine;
  }
  /// Copies the subtree of inner node `node` depth first; @return its index in `out`.
  uint32_t copySubtree(Parts& out, uint32_t node) const {
    const auto me = static_cast<uint32_t>(out.inner.size());
    out.inner.emplace_back();
    out.inner[me].fill(kEmpty);
    for (int slot = 0; slot < 8; ++slot) {
      const Ref r = src_.inner[node][static_cast<size_t>(slot)];
      Ref mine = kEmpty;
      if (r == kEmpty) {
        mine = kEmpty;
      } else if (r & kListBit) {
        mine = copyList(out, r);
      } else {
        mine = copySubtree(out, r);
      }
      out.inner[me][static_cast<size_t>(slot)] = mine;
    }
    return me;
  }

 private:
  const Parts& src_;
  std::vector<uint64_t> offsets_;
};

/// The inner node of `p` that holds the tile at `corner`, after checking that the path to it
/// holds nothing else. @throw FormatError.
uint32_t tileRoot(const Parts& p, const VoxelKey& corner, int tile_level, const std::string& source) {
  uint32_t node = 0;
  for (int level = kTreeDepth; level > tile_level; --level) {
    const int want = childSlot(corner, level - 1);
    const TemporalMap::Children children = p.inner[node];
    for (int slot = 0; slot < 8; ++slot) {
      const Ref r = children[static_cast<size_t>(slot)];
      if (slot == want) {
        if (r == kEmpty || (r & kListBit)) throw FormatError(source + " does not hold its tile's subtree");
        node = r;
      } else if (r != kEmpty) {
        throw FormatError(source + " holds nodes outside its tile");
      }
    }
  }
  return node;
}

/// Builds the Parts of a map holding only the subtree `node` of `copier`'s source, hung at
/// `corner` (a cube of 2^tile_level voxels per axis).
Parts tileParts(const PartsCopier& copier, uint32_t node, const VoxelKey& corner, int tile_level) {
  Parts out;
  out.inner.emplace_back();
  out.inner[0].fill(kEmpty);
  uint32_t at = 0;
  for (int level = kTreeDepth; level > tile_level + 1; --level) {
    const auto next = static_cast<uint32_t>(out.inner.size());
    out.inner.emplace_back();
    out.inner[next].fill(kEmpty);
    out.inner[at][static_cast<size_t>(childSlot(corner, level - 1))] = next;
    at = next;
  }
  const uint32_t sub = copier.copySubtree(out, node);
  out.inner[at][static_cast<size_t>(childSlot(corner, tile_level))] = sub;
  return out;
}

void checkTileLevel(int tile_level) {
  if (tile_level < kMinTileLevel || tile_level > kMaxTileLevel) {
    throw UsageError("tile level must lie in [" + std::to_string(kMinTileLevel) + ", " + std::to_string(kMaxTileLevel) +
                     "], got " + std::to_string(tile_level));
  }
}

}  // namespace

Coverage clipCoverage(const Coverage& coverage, const VoxelKey& corner, int level) {
  const uint64_t lo = mortonEncode(corner);
  const uint64_t hi = lo + (uint64_t{1} << (3 * level));
  const std::vector<uint64_t> all = coverage.ranges();
  std::vector<uint64_t> kept;
  for (size_t i = 0; i + 1 < all.size(); i += 2) {
    const uint64_t b = std::max(all[i], lo), e = std::min(all[i + 1], hi);
    if (b < e) {
      kept.push_back(b);
      kept.push_back(e);
    }
  }
  return Coverage::fromRanges(kept);
}

Coverage clipCoverageOutside(const Coverage& coverage, const std::vector<TileKey>& tiles, int tile_level) {
  // The tiles as Morton ranges (a cube is one range), sorted; then one sweep.
  std::vector<std::pair<uint64_t, uint64_t>> cut;
  cut.reserve(tiles.size());
  for (const TileKey& t : tiles) {
    const uint64_t lo = mortonEncode(tileCorner(t, tile_level));
    cut.emplace_back(lo, lo + (uint64_t{1} << (3 * tile_level)));
  }
  std::sort(cut.begin(), cut.end());
  const std::vector<uint64_t> all = coverage.ranges();
  std::vector<uint64_t> kept;
  size_t c = 0;
  for (size_t i = 0; i + 1 < all.size(); i += 2) {
    uint64_t b = all[i];
    const uint64_t e = all[i + 1];
    while (c < cut.size() && cut[c].second <= b) ++c;
    for (size_t k = c; k < cut.size() && cut[k].first < e && b < e; ++k) {
      if (cut[k].first > b) {
        kept.push_back(b);
        kept.push_back(cut[k].first);
      }
      b = std::max(b, cut[k].second);
    }
    if (b < e) {
      if (!kept.empty() && kept.back() == b) {
        kept.back() = e;
      } else {
        kept.push_back(b);
        kept.push_back(e);
      }
    }
  }
  return Coverage::fromRanges(kept);
}

Coverage unionCoverage(const std::vector<const Coverage*>& parts) {
  std::vector<std::pair<uint64_t, uint64_t>> all;
  for (const Coverage* c : parts) {
    const std::vector<uint64_t> r = c->ranges();
    for (size_t i = 0; i + 1 < r.size(); i += 2) all.emplace_back(r[i], r[i + 1]);
  }
  std::sort(all.begin(), all.end());
  std::vector<uint64_t> merged;
  for (const auto& [b, e] : all) {
    if (!merged.empty() && b <= merged.back()) {
      merged.back() = std::max(merged.back(), e);  // overlapping or touching: one range
    } else {
      merged.push_back(b);
      merged.push_back(e);
    }
  }
  return Coverage::fromRanges(merged);
}

SplitMap splitIntoTiles(const TemporalMap& map, int tile_level) {
  checkTileLevel(tile_level);
  const Parts p = map.parts();
  const PartsCopier copier(p);
  struct Found {
    TileKey key;
    uint32_t node;
  };
  std::vector<Found> found;
  Parts top;
  auto copyTop = [&](auto&& self, uint32_t node, int level, const VoxelKey& corner) -> uint32_t {
    const auto me = static_cast<uint32_t>(top.inner.size());
    top.inner.emplace_back();
    top.inner[me].fill(kEmpty);
    for (int slot = 0; slot < 8; ++slot) {
      const Ref r = p.inner[node][static_cast<size_t>(slot)];
      const int child_level = level - 1;
      const VoxelKey child = childCorner(corner, slot, child_level);
      Ref mine = kEmpty;
      if (r == kEmpty) {
        mine = kEmpty;
      } else if (r & kListBit) {
        mine = copier.copyList(top, r);  // a cube of tile size or larger: kept whole in the top
      } else if (child_level == tile_level) {
        found.push_back(Found{tileOf(child, tile_level), r});
      } else {
        mine = self(self, r, child_level, child);
      }
      top.inner[me][static_cast<size_t>(slot)] = mine;
    }
    return me;
  };
  copyTop(copyTop, 0, kTreeDepth, VoxelKey{});

  std::vector<TileKey> keys;
  keys.reserve(found.size());
  for (const Found& f : found) keys.push_back(f.key);
  std::vector<SessionRecord> top_sessions = map.sessions();
  for (SessionRecord& s : top_sessions) s.coverage = clipCoverageOutside(s.coverage, keys, tile_level);
  SplitMap out{tile_level,
               TemporalMap::fromParts(map.resolution_m(), map.criterion(), std::move(top), std::move(top_sessions)),
               {}};
  out.tiles.reserve(found.size());
  for (const Found& f : found) {
    const VoxelKey corner = tileCorner(f.key, tile_level);
    std::vector<SessionRecord> sessions;
    sessions.reserve(map.sessionCount());
    for (const SessionRecord& s : map.sessions()) {
      SessionRecord r;
      r.time_s = s.time_s;
      r.name = s.name;
      r.coverage = clipCoverage(s.coverage, corner, tile_level);
      sessions.push_back(std::move(r));
    }
    out.tiles.push_back(Tile{f.key, TemporalMap::fromParts(map.resolution_m(), map.criterion(),
                                                           tileParts(copier, f.node, corner, tile_level),
                                                           std::move(sessions))});
  }
  return out;
}

void checkFitsTileCube(const TemporalMap& top, int tile_level, const TileKey& key, const TemporalMap& part,
                       int max_level, const std::string& source) {
  if (part.resolution_m() != top.resolution_m()) {
    throw FormatError(source + ": resolution " + std::to_string(part.resolution_m()) + " m differs from the index's " +
                      std::to_string(top.resolution_m()) + " m");
  }
  if (!(part.criterion() == top.criterion())) {
    throw FormatError(source + ": its change criterion differs from the index's");
  }
  // Every history list inside the cube (a walk, not a copy of the pools; the join checks the
  // shape of the path as it grafts).
  bool inside = true;
  part.forEachListPlace([&](const VoxelKey& corner, int level) {
    inside = inside && level <= max_level && tileOf(corner, tile_level) == key;
  });
  if (!inside) throw FormatError(source + " holds nodes outside its tile");
}

void checkTileFits(const TemporalMap& top, int tile_level, const TileKey& key, const TemporalMap& tile,
                   const std::string& source) {
  checkFitsTileCube(top, tile_level, key, tile, tile_level - 1, source);  // every list below tile level
  bool same = tile.sessionCount() == top.sessionCount();
  for (size_t i = 0; same && i < tile.sessionCount(); ++i) same = tile.sessions()[i].time_s == top.sessions()[i].time_s;
  if (!same) {
    throw FormatError(source + ": its sessions (" + std::to_string(tile.sessionCount()) +
                      ") do not match the index's sessions table (" + std::to_string(top.sessionCount()) + ")");
  }
}

TemporalMap joinTiles(const TemporalMap& top, int tile_level, const std::vector<const Tile*>& tiles) {
  checkTileLevel(tile_level);
  std::map<TileKey, const Tile*> by_key;
  for (const Tile* t : tiles) {
    if (!by_key.emplace(t->key, t).second) throw FormatError(tileName(t->key) + " is given twice");
  }
  const Parts p = top.parts();
  const PartsCopier copier(p);
  Parts out;
  size_t grafted = 0;
  auto copy = [&](auto&& self, uint32_t node, int level, const VoxelKey& corner) -> uint32_t {
    const auto me = static_cast<uint32_t>(out.inner.size());
    out.inner.emplace_back();
    out.inner[me].fill(kEmpty);
    for (int slot = 0; slot < 8; ++slot) {
      const Ref r = p.inner[node][static_cast<size_t>(slot)];
      const int child_level = level - 1;
      const VoxelKey child = childCorner(corner, slot, child_level);
      Ref mine = kEmpty;
      if (r != kEmpty && (r & kListBit)) {
        mine = copier.copyList(out, r);
      } else if (r != kEmpty) {
        mine = self(self, r, child_level, child);
      } else if (child_level == tile_level) {
        const auto it = by_key.find(tileOf(child, tile_level));
        if (it != by_key.end()) {
          const std::string name = tileName(it->first);
          checkTileFits(top, tile_level, it->first, it->second->map, name);
          const Parts tp = it->second->map.parts();
          mine = PartsCopier(tp).copySubtree(out, tileRoot(tp, child, tile_level, name));
          ++grafted;
        }
      }
      out.inner[me][static_cast<size_t>(slot)] = mine;
    }
    return me;
  };
  copy(copy, 0, kTreeDepth, VoxelKey{});
  if (grafted != by_key.size()) {
    throw FormatError(std::to_string(by_key.size() - grafted) + " tile(s) have no place in the index's tree");
  }
  std::vector<SessionRecord> sessions = top.sessions();
  for (size_t i = 0; i < sessions.size() && !tiles.empty(); ++i) {
    std::vector<const Coverage*> parts = {&sessions[i].coverage};
    for (const Tile* t : tiles) parts.push_back(&t->map.sessions()[i].coverage);
    sessions[i].coverage = unionCoverage(parts);
  }
  return TemporalMap::fromParts(top.resolution_m(), top.criterion(), std::move(out), std::move(sessions));
}

namespace {

/// The reference `p` holds in the slot of `cube` (kEmpty when the path to it ends first), and
/// whether a list above the cube holds it (then *inside_list is set).
Ref refAt(const Parts& p, const Cube& cube, bool* inside_list = nullptr) {
  uint32_t node = 0;
  for (int level = kTreeDepth; level > cube.level; --level) {
    const Ref r = p.inner[node][static_cast<size_t>(childSlot(cube.corner, level - 1))];
    if (level - 1 == cube.level) return r;
    if (r == kEmpty) return kEmpty;
    if (r & kListBit) {
      if (inside_list) *inside_list = true;
      return kEmpty;
    }
    node = r;
  }
  return kEmpty;
}

}  // namespace

TemporalMap restrictToCube(const TemporalMap& map, const Cube& cube, std::vector<SessionRecord> sessions) {
  if (cube.level < 0 || cube.level >= kTreeDepth) throw UsageError("cube level out of range");
  const Parts p = map.parts();
  const PartsCopier copier(p);
  Parts out;
  out.inner.emplace_back();
  out.inner[0].fill(kEmpty);
  uint32_t at = 0;
  for (int level = kTreeDepth; level > cube.level + 1; --level) {
    const auto next = static_cast<uint32_t>(out.inner.size());
    out.inner.emplace_back();
    out.inner[next].fill(kEmpty);
    out.inner[at][static_cast<size_t>(childSlot(cube.corner, level - 1))] = next;
    at = next;
  }
  bool inside_list = false;
  const Ref r = refAt(p, cube, &inside_list);
  if (inside_list) throw FormatError("a cube to restrict to lies inside a uniform cube of the map");
  Ref mine = kEmpty;
  if (r != kEmpty) mine = (r & kListBit) ? copier.copyList(out, r) : copier.copySubtree(out, r);
  out.inner[at][static_cast<size_t>(childSlot(cube.corner, cube.level))] = mine;
  return TemporalMap::fromParts(map.resolution_m(), map.criterion(), std::move(out), std::move(sessions));
}

TemporalMap replaceCubes(const TemporalMap& top, const std::vector<CubePart>& parts,
                         std::vector<SessionRecord> sessions) {
  const Parts p = top.parts();
  const PartsCopier copier(p);
  std::vector<Parts> from_parts;
  from_parts.reserve(parts.size());
  for (const CubePart& c : parts) from_parts.push_back(c.from->parts());
  Parts out;
  size_t placed = 0;
  // Index of the part whose cube is `cube`, -1 if none; -2 when a part lies strictly inside.
  auto find = [&](const Cube& cube) -> int {
    int inside = -1;
    for (size_t i = 0; i < parts.size(); ++i) {
      if (parts[i].cube == cube) return static_cast<int>(i);
      if (cube.contains(parts[i].cube)) inside = -2;
    }
    return inside;
  };
  auto copy = [&](auto&& self, uint32_t node, bool exists, int level, const VoxelKey& corner) -> uint32_t {
    const auto me = static_cast<uint32_t>(out.inner.size());
    out.inner.emplace_back();
    out.inner[me].fill(kEmpty);
    for (int slot = 0; slot < 8; ++slot) {
      const Ref r = exists ? p.inner[node][static_cast<size_t>(slot)] : kEmpty;
      const int child_level = level - 1;
      const Cube child{childCorner(corner, slot, child_level), child_level};
      const int which = find(child);
      Ref mine = kEmpty;
      if (which >= 0) {
        const Parts& fp = from_parts[static_cast<size_t>(which)];
        const Ref fr = refAt(fp, child);
        if (fr != kEmpty) {
          const PartsCopier from_copier(fp);
          mine = (fr & kListBit) ? from_copier.copyList(out, fr) : from_copier.copySubtree(out, fr);
        }
        ++placed;
      } else if (which == -2) {
        if (r != kEmpty && (r & kListBit)) throw FormatError("a cube to replace lies inside a uniform cube");
        mine = self(self, r, r != kEmpty, child_level, child.corner);
      } else if (r != kEmpty) {
        mine = (r & kListBit) ? copier.copyList(out, r) : copier.copySubtree(out, r);
      }
      out.inner[me][static_cast<size_t>(slot)] = mine;
    }
    return me;
  };
  copy(copy, 0, true, kTreeDepth, VoxelKey{});
  if (placed != parts.size()) throw FormatError("cubes to replace overlap");
  return TemporalMap::fromParts(top.resolution_m(), top.criterion(), std::move(out), std::move(sessions));
}

}  // namespace chronomap
