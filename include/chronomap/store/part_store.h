#pragma once
/// @file
/// The streaming build's spill store: the leaves of the sessions being added, grouped by the
/// cube (tile or larger) they fall in, held in memory under a byte limit and appended to one
/// file per cube beyond it (docs/scale.md, "The streaming build"). The files are the build's
/// scratch, removed with the store; no other program reads them.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <type_traits>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/temporal/tiles.h"

namespace chronomap {

/// One leaf of a session map, as held and spilled.
struct SessionPart {
  uint32_t session = 0;  ///< the index its producer gave the session
  uint16_t x = 0, y = 0, z = 0;
  uint8_t level = 0;
  uint8_t unused = 0;
  VoxelCounters counters;
};
static_assert(std::is_trivially_copyable_v<SessionPart>);

/// Cubes from the largest down, then in Morton order of their corners.
struct CubeLess {
  bool operator()(const Cube& a, const Cube& b) const {
    if (a.level != b.level) return a.level > b.level;
    return mortonEncode(a.corner) < mortonEncode(b.corner);
  }
};

/// What a PartStore did.
struct PartStoreStats {
  size_t spills = 0;          ///< times the held parts were written out to make room
  uint64_t spilled_bytes = 0;
  size_t peak_bytes = 0;      ///< most bytes of parts held at once (at most the limit)
};

/// Session parts by cube, in memory under `limit_bytes` (0: no limit), spilled to files in
/// `folder` beyond it. The folder is created on the first spill and removed with the store.
class PartStore {
 public:
  PartStore(std::filesystem::path folder, size_t limit_bytes);
  ~PartStore();
  PartStore(const PartStore&) = delete;
  PartStore& operator=(const PartStore&) = delete;

  /// Keeps `part` under `cube`, spilling every held part first when it would pass the limit.
  /// @throw IoError when a spill cannot be written.
  void add(const Cube& cube, const SessionPart& part);
  /// Every cube that received a part.
  const std::set<Cube, CubeLess>& cubes() const { return cubes_; }
  /// Every part of `cube`, spilled or held (spilled first, in the order added); they leave the store.
  std::vector<SessionPart> take(const Cube& cube);
  const PartStoreStats& stats() const { return stats_; }

 private:
  void spill();

  std::filesystem::path folder_;
  size_t limit_;
  PartStoreStats stats_;
  bool created_ = false;
  size_t bytes_ = 0;
  std::map<Cube, std::vector<SessionPart>, CubeLess> held_;
  std::set<Cube, CubeLess> cubes_;
};

}  // namespace chronomap
