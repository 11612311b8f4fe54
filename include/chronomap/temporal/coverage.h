#pragma once
/// @file
/// Which voxels one session observed: sorted, disjoint Morton-code ranges.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// The known voxels of a session map, kept by the 4D map so that a session inserted before
/// later ones can tell which later session saw a voxel next. A leaf at level k covers the 8^k
/// consecutive Morton codes starting at its corner, so the known set of a map is a short list
/// of ranges (one per run of known leaves in Morton order).
class Coverage {
 public:
  /// How a cube relates to the covered set.
  enum class Overlap { None, Partial, Full };

  Coverage() = default;
  /// The known voxels (unit or compressed leaves) of `map`.
  explicit Coverage(const SessionMap& map);
  /// From [begin, end) pairs. @throw FormatError if they are not sorted, disjoint and in range.
  static Coverage fromRanges(std::vector<uint64_t> begin_end_pairs);

  /// How the cube with lower corner `corner` at `level` (2^level voxels per axis) overlaps.
  Overlap overlap(const VoxelKey& corner, int level) const;
  /// True when the unit voxel `key` was observed.
  bool contains(const VoxelKey& key) const { return overlap(key, 0) == Overlap::Full; }

  /// Flattened [begin, end) pairs of Morton codes.
  const std::vector<uint64_t>& ranges() const { return ranges_; }
  /// Number of unit voxels covered.
  uint64_t voxelCount() const;
  size_t memoryBytes() const { return ranges_.size() * sizeof(uint64_t); }

  friend bool operator==(const Coverage&, const Coverage&) = default;

 private:
  std::vector<uint64_t> ranges_;
};

}  // namespace chronomap
