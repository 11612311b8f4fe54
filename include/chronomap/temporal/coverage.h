#pragma once
/// @file
/// Which voxels one session observed: sorted, disjoint Morton-code ranges, kept compressed.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// The known voxels of a session map, kept by the 4D map so that a session inserted before
/// later ones can tell which later session saw a voxel next. A leaf at level k covers the 8^k
/// consecutive Morton codes starting at its corner, so the known set of a map is a list of
/// ranges (one per run of known leaves in Morton order). They are stored as variable-length
/// integers (the count, then per range the gap from the previous range and the length), which
/// is also their form on disk; CoverageIndex decodes them for queries.
class Coverage {
 public:
  Coverage() = default;
  /// The known voxels (unit or compressed leaves) of `map`.
  explicit Coverage(const SessionMap& map);
  /// From [begin, end) pairs. @throw FormatError if they are not sorted, disjoint and in range.
  static Coverage fromRanges(const std::vector<uint64_t>& begin_end_pairs);
  /// Reads one encoded coverage starting at `pos` and advances `pos` past it.
  /// @throw FormatError for truncated or invalid encodings.
  static Coverage decodeFrom(const std::vector<uint8_t>& bytes, size_t& pos);

  /// Flattened [begin, end) pairs of Morton codes.
  std::vector<uint64_t> ranges() const;
  /// The encoded form (appended as is to a file).
  const std::vector<uint8_t>& encoded() const { return encoded_; }
  /// Number of unit voxels covered.
  uint64_t voxelCount() const { return voxels_; }
  size_t memoryBytes() const { return encoded_.capacity() + sizeof(Coverage); }

  friend bool operator==(const Coverage&, const Coverage&) = default;

 private:
  std::vector<uint8_t> encoded_;
  uint64_t voxels_ = 0;
};

/// A decoded Coverage for fast queries (binary search over the ranges).
class CoverageIndex {
 public:
  /// How a cube relates to the covered set.
  enum class Overlap { None, Partial, Full };

  explicit CoverageIndex(const Coverage& coverage) : ranges_(coverage.ranges()) {}
  /// How the cube with lower corner `corner` at `level` (2^level voxels per axis) overlaps.
  Overlap overlap(const VoxelKey& corner, int level) const;
  /// True when the unit voxel `key` was observed.
  bool contains(const VoxelKey& key) const { return overlap(key, 0) == Overlap::Full; }

 private:
  std::vector<uint64_t> ranges_;
};

}  // namespace chronomap
