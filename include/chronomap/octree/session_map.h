#pragma once
/// @file
/// The session map: one octree of voxel counters for one recording (thesis §2.1).

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/core/tree_walk.h"

namespace chronomap {

/// One leaf of a session map as seen by iteration: the voxel's lower-corner key, its level
/// (0 = unit voxel; k > 0 = a compressed known-free node spanning 2^k voxels per axis) and its
/// summed counters.
struct LeafView {
  VoxelKey key;
  int level = 0;
  VoxelCounters counters;
};

/// Counts of what a session map holds.
struct SessionMapCounts {
  size_t inner_nodes = 0;       ///< nodes with children (the root included)
  size_t leaves = 0;            ///< leaf nodes (unit voxels and compressed nodes)
  size_t compressed_leaves = 0; ///< leaves above unit level
  uint64_t occupied_voxels = 0; ///< unit voxels whose state is occupied
  uint64_t free_voxels = 0;     ///< unit voxels whose state is free (compressed nodes expanded)
};

/// An octree of VoxelCounters with a fixed depth (kTreeDepth) and resolution.
///
/// Storage is three flat pools addressed by 32-bit references: inner nodes (8 child references,
/// 32 bytes), leaves with every counter (32 bytes) and free leaves, whose only non-zero counter
/// is the ray length (4 bytes: most of a map's leaves, which rays crossed and none ended in). A
/// free leaf that a hit reaches moves to the other pool. No node owns heap memory. A leaf above
/// unit level is a compressed known-free node: its counters are the sums of the 2^(3k) unit
/// voxels it replaced; when an update reaches inside it, it is split evenly into 8 children.
class SessionMap {
 public:
  /// @throw UsageError for a resolution that is not a finite positive number.
  explicit SessionMap(double resolution_m = 0.05);

  const KeyGrid& grid() const { return grid_; }
  double resolution_m() const { return grid_.resolution_m(); }

  /// Adds `delta` to the unit voxel `key`, refining compressed nodes on the way.
  void add(const VoxelKey& key, const VoxelCounters& delta);
  /// Adds many deltas. Correct for any order; fastest when consecutive keys are close
  /// (raster or Morton order), because the descent restarts at their common ancestor.
  void addMany(std::span<const VoxelKey> keys, std::span<const VoxelCounters> deltas);
  /// Adds `sums`, the summed counters of the cube of 2^level voxels per axis at `corner`, spread
  /// evenly over its unit voxels: a compressed node where the cube holds nothing yet, the sums
  /// split in eighths where it is already finer.
  /// @throw UsageError for a level above kTreeDepth - 1, a corner not aligned to the level, or
  /// a cube above unit level with hits (only known-free cubes can be spread).
  void addCube(const VoxelKey& corner, int level, const VoxelCounters& sums);
  /// addCube() for many known-free cubes of one level (above unit level), each with only a
  /// length (metres), which may be zero (nothing is added). Fastest when consecutive corners are
  /// close (raster or Morton order): the descent restarts at their common ancestor.
  /// @throw UsageError for a level outside 1 .. kTreeDepth - 1, a corner not aligned to it, or
  /// spans of different lengths.
  void addCubes(std::span<const VoxelKey> corners, int level, std::span<const float> lengths_m);
  /// Adds every counter of `other` (same resolution) to this map, volume by volume; a
  /// compressed node of either map is spread evenly where the other is finer (the consensus
  /// of §2.2). Linear in the nodes of both maps.
  /// @throw UsageError for a different resolution.
  void merge(const SessionMap& other);
  /// Sets the unit voxel `key` to `value`, or makes it unknown when `value` is empty; a
  /// compressed node around it is split first. Leaves garbage in the pools until the next
  /// compressFree().
  void assign(const VoxelKey& key, const std::optional<VoxelCounters>& value);

  /// Counters of the unit voxel `key`; for a voxel inside a compressed node, that node's sums
  /// divided evenly. Nothing when the voxel was never observed.
  std::optional<VoxelCounters> find(const VoxelKey& key) const;
  /// The leaf that contains `key` (unit or compressed), or nothing.
  std::optional<LeafView> findLeaf(const VoxelKey& key) const;
  /// State of the unit voxel `key` (Unknown when never observed).
  VoxelState stateOf(const VoxelKey& key) const;

  /// Calls fn(const LeafView&) for every leaf, in Morton order of the leaves' keys.
  template <class Fn>
  void forEachLeaf(Fn&& fn) const;

  /// Merges every node whose 8 children are known-free leaves without hits into one leaf
  /// holding their sums, recursively, then re-lays the pools out in depth-first order (inner
  /// nodes left without children are dropped).
  /// @return the number of leaves removed.
  size_t compressFree();

  /// Counts nodes and voxel states (linear in the number of nodes).
  SessionMapCounts counts() const;
  /// Number of leaves (unit and compressed).
  size_t leafCount() const { return leaves_.size() + free_.size() - moved_; }
  /// Number of inner nodes, the root included.
  size_t innerCount() const { return inner_.size(); }
  /// Bytes of node storage in use (pool sizes, not capacities).
  size_t memoryBytes() const;
  /// Bytes reserved by the pools (what the process really holds).
  size_t reservedBytes() const;
  /// True when nothing was ever added.
  bool empty() const { return leaves_.empty() && free_.empty(); }

  /// Low-level access: references are kEmpty, an inner index, or a leaf (kLeafBit set; which
  /// pool and where is the map's own business: read it with leaf()). The root is inner node 0.
  using Ref = uint32_t;
  static constexpr Ref kEmpty = 0xffffffffu;
  static constexpr Ref kLeafBit = 0x80000000u;
  using Children = std::array<Ref, 8>;
  const std::vector<Children>& innerPool() const { return inner_; }
  /// The counters of leaf reference `r` (one of innerPool()'s).
  VoxelCounters leaf(Ref r) const {
    if ((r & kFreeBit) == 0) return leaves_[index(r)];
    VoxelCounters c;
    c.length_m = free_[index(r)];
    return c;
  }
  /// The tree as two pools in depth-first order (inner nodes in pre-order, leaves in visit
  /// order), with leaf references kLeafBit | index into `leaves`: what writers store, whatever
  /// the pools' layout in memory.
  struct Pools {
    std::vector<Children> inner;
    std::vector<VoxelCounters> leaves;
  };
  Pools pools() const;
  /// Replaces the pools (used by readers): leaf references kLeafBit | index into `leaves`.
  /// @throw FormatError if the pools do not form a valid tree of depth kTreeDepth.
  void assignPools(std::vector<Children> inner, std::vector<VoxelCounters> leaves);

  friend bool operator==(const SessionMap& a, const SessionMap& b);

 private:
  friend class TemporalMap;  // builds snapshots whose pools are valid by construction
  /// Every leaf stays in the full pool (a snapshot is built and read, not integrated into).
  void adoptPools(std::vector<Children> inner, std::vector<VoxelCounters> leaves) {
    inner_ = std::move(inner);
    leaves_ = std::move(leaves);
    free_.clear();
    moved_ = 0;
  }

  /// Set with kLeafBit: a free leaf, an index into free_.
  static constexpr Ref kFreeBit = 0x40000000u;
  static bool isLeaf(Ref r) { return r != kEmpty && (r & kLeafBit) != 0; }
  static bool isInner(Ref r) { return r != kEmpty && (r & kLeafBit) == 0; }
  static bool isFreeLeaf(Ref r) { return (r & (kLeafBit | kFreeBit)) == (kLeafBit | kFreeBit) && r != kEmpty; }
  static uint32_t index(Ref r) { return r & ~(kLeafBit | kFreeBit); }
  /// True for counters a free leaf holds exactly: nothing but a length (bit for bit: a
  /// negative zero offset is kept in the other pool).
  static bool freeOnly(const VoxelCounters& c);
  /// A new leaf holding `c`, in the pool that fits it.
  Ref newLeaf(const VoxelCounters& c);
  /// Adds `delta` to the leaf `ref`, moving it to the full pool when it no longer fits the free one.
  void addToLeaf(Ref& ref, const VoxelCounters& delta);
  /// Sets the leaf `ref` to `c` (in place when its pool fits `c`).
  void setLeaf(Ref& ref, const VoxelCounters& c);
  /// Moves every free-only leaf to the free pool, laying the pools out depth first.
  void separateFree();
  Ref newInner();
  /// Replaces the compressed leaf in slot `slot` of inner node `parent` (leaf at `level`) by an
  /// inner node whose 8 children hold an eighth of its counters each.
  uint32_t splitLeaf(uint32_t parent, int slot);
  /// Returns the inner node for the child `slot` of `parent`, creating or splitting as needed.
  uint32_t descend(uint32_t parent, int slot);
  /// merge()'s recursion: adds the subtree `src` of `other` (cube at `level`) into slot `slot`
  /// of inner node `parent`.
  void mergeInto(uint32_t parent, int slot, int level, const SessionMap& other, Ref src);
  /// Spreads `sums` of a known-free cube at `level` over slot `slot` of `parent`.
  void spreadInto(uint32_t parent, int slot, int level, const VoxelCounters& sums);
  /// compressFree's pass: copyInto() (dropping inner nodes without children) that also replaces
  /// an inner node other than the root, whose eight children are (after their own replacement)
  /// leaves known free without hits, by one free leaf: the sum of their lengths in slot order.
  /// `known_free` tells whether the copy of `r` is such a leaf.
  Ref compressInto(Ref r, std::vector<Children>& inner, std::vector<VoxelCounters>& leaves, std::vector<float>& free,
                   bool& known_free) const;
  /// Appends leaf `c` to `free` when it is free-only and `free` is given, else to `leaves`;
  /// returns its reference in those pools.
  static Ref pushLeaf(const VoxelCounters& c, std::vector<VoxelCounters>& leaves, std::vector<float>* free);
  /// Copies the subtree `r` depth first into fresh pools, inner nodes without children
  /// included (pools(), separateFree(); compressFree() drops them); returns its new reference.
  /// Leaves go to `leaves` or, free-only and when `free` is given, to `free`.
  Ref copyInto(Ref r, std::vector<Children>& inner, std::vector<VoxelCounters>& leaves, std::vector<float>* free) const;

  KeyGrid grid_;
  std::vector<Children> inner_;
  std::vector<VoxelCounters> leaves_;
  std::vector<float> free_;
  size_t moved_ = 0;  ///< slots of free_ left behind by leaves that moved to leaves_
};

template <class Fn>
void SessionMap::forEachLeaf(Fn&& fn) const {
  walkPoolTree(
      inner_, kLeafBit, [](uint32_t) { return true; },
      [&](Ref r, const VoxelKey& k, int level) { fn(LeafView{k, level, leaf(r)}); });
}

}  // namespace chronomap
