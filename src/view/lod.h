#pragma once
// Level of detail over occupied lists in Morton order, shared by snapshots and tours.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "chronomap/view/scene.h"

namespace chronomap::lod {

/// Cell id of an item (a Morton code `code` of a cube at `level`) at level of detail `lod`:
/// the code without the bits below the cell, tagged with the level, so that a larger uniform
/// cube never merges with a smaller cell.
inline uint64_t cellId(uint64_t code, int level, int lod) {
  const int l = std::max(lod, level);
  return ((code >> (3 * l)) << 4) | static_cast<uint64_t>(l);
}

/// The finest level in [min_level, kMaxLevel] at which the items (in Morton order, fields
/// `code` and `level`) fall into at most max_cells cells; kMaxLevel when none does.
template <class Items>
int chooseLevel(const Items& items, int min_level, size_t max_cells) {
  std::array<size_t, kMaxLevel + 1> cells{};
  std::array<uint64_t, kMaxLevel + 1> previous{};
  previous.fill(std::numeric_limits<uint64_t>::max());
  for (const auto& o : items) {
    for (int l = min_level; l <= kMaxLevel; ++l) {
      const uint64_t id = cellId(o.code, o.level, l);
      if (id != previous[l]) {
        previous[l] = id;
        ++cells[l];
      }
    }
  }
  for (int l = min_level; l <= kMaxLevel; ++l) {
    if (cells[l] <= max_cells) return l;
  }
  return kMaxLevel;
}

/// Unit voxels in a cube at `level` (saturating).
inline uint64_t unitVoxels(int level) {
  return level >= 21 ? std::numeric_limits<uint64_t>::max() : uint64_t{1} << (3 * level);
}


}  // namespace chronomap::lod
