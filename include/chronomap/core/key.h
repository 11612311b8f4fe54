#pragma once
/// @file
/// Voxel keys: integer coordinates of unit voxels in a tree of fixed depth, and Morton codes.

#include <cmath>
#include <compare>
#include <cstdint>
#include <optional>

#include <Eigen/Core>

namespace chronomap {

/// Depth of every chronomap octree; the root spans 2^16 unit voxels per axis (as in OctoMap,
/// so keys convert to OctoMap keys one to one).
inline constexpr int kTreeDepth = 16;
/// Key of the voxel whose lower corner is the map origin (0, 0, 0).
inline constexpr int32_t kKeyOrigin = 1 << (kTreeDepth - 1);
/// Number of unit voxels per axis.
inline constexpr int32_t kKeysPerAxis = 1 << kTreeDepth;
/// Length of the map's space diagonal in unit voxels (sqrt(3) * 2^16): no two points of the map
/// lie farther apart, so a longer sensor range reaches nothing more.
inline constexpr double kMapDiagonalVoxels = 1.7320508075688772 * kKeysPerAxis;
/// Finest and coarsest unit voxel edge a map may have, in metres: the map then spans 6.55 m or
/// 65,536 km per axis. Points are single-precision metres, so finer voxels would be noise.
inline constexpr double kMinResolution_m = 1e-4;
inline constexpr double kMaxResolution_m = 1e3;

/// Integer coordinates of a unit voxel; each in [0, 2^16).
struct VoxelKey {
  uint16_t x = 0;
  uint16_t y = 0;
  uint16_t z = 0;
  friend constexpr auto operator<=>(const VoxelKey&, const VoxelKey&) = default;
};

/// Interleaves the bits of a key into a 48-bit Morton code (x in the lowest bit of each triple).
constexpr uint64_t mortonEncode(const VoxelKey& key) {
  auto spread = [](uint64_t v) {
    v &= 0xffff;
    v = (v | (v << 16)) & 0x0000ff0000ffULL;
    v = (v | (v << 8)) & 0x00f00f00f00fULL;
    v = (v | (v << 4)) & 0x0c30c30c30c3ULL;
    v = (v | (v << 2)) & 0x249249249249ULL;
    return v;
  };
  return spread(key.x) | (spread(key.y) << 1) | (spread(key.z) << 2);
}

/// Inverse of mortonEncode.
constexpr VoxelKey mortonDecode(uint64_t code) {
  auto compact = [](uint64_t v) {
    v &= 0x249249249249ULL;
    v = (v | (v >> 2)) & 0x0c30c30c30c3ULL;
    v = (v | (v >> 4)) & 0x00f00f00f00fULL;
    v = (v | (v >> 8)) & 0x0000ff0000ffULL;
    v = (v | (v >> 16)) & 0xffff;
    return static_cast<uint16_t>(v);
  };
  return VoxelKey{compact(code), compact(code >> 1), compact(code >> 2)};
}

/// Lower corner of child `slot` (bit 0: +x, bit 1: +y, bit 2: +z) of the node whose lower
/// corner is `base`, the child being at `child_level` (2^child_level voxels per axis).
constexpr VoxelKey childCorner(const VoxelKey& base, int slot, int child_level) {
  const auto step = static_cast<uint16_t>(1u << child_level);
  VoxelKey k = base;
  if (slot & 1) k.x = static_cast<uint16_t>(k.x + step);
  if (slot & 2) k.y = static_cast<uint16_t>(k.y + step);
  if (slot & 4) k.z = static_cast<uint16_t>(k.z + step);
  return k;
}

/// The child slot (bit 0: +x, bit 1: +y, bit 2: +z) that holds `key` in a node whose children are
/// at `child_level`.
constexpr int childSlot(const VoxelKey& key, int child_level) {
  return ((key.x >> child_level) & 1) | (((key.y >> child_level) & 1) << 1) | (((key.z >> child_level) & 1) << 2);
}

/// The lower corner of the cube at `level` (2^level voxels per axis) that holds `key`.
constexpr VoxelKey cellCorner(const VoxelKey& key, int level) {
  const auto mask = static_cast<uint16_t>(~((1u << level) - 1u));
  return VoxelKey{static_cast<uint16_t>(key.x & mask), static_cast<uint16_t>(key.y & mask),
                  static_cast<uint16_t>(key.z & mask)};
}

/// The key (dx, dy, dz) voxels away from `key`, or nothing outside the key space.
inline std::optional<VoxelKey> offsetKey(const VoxelKey& key, int dx, int dy, int dz) {
  const int x = key.x + dx, y = key.y + dy, z = key.z + dz;
  if (x < 0 || y < 0 || z < 0 || x >= kKeysPerAxis || y >= kKeysPerAxis || z >= kKeysPerAxis) return std::nullopt;
  return VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)};
}

/// Calls fn(const VoxelKey&) for every key within Chebyshev distance r of `key` (itself
/// included) that lies inside the key space: z, then y, then x ascending.
template <class Fn>
void forEachKeyInCube(const VoxelKey& key, int r, Fn&& fn) {
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        if (const auto k = offsetKey(key, dx, dy, dz)) fn(*k);
      }
    }
  }
}

/// Calls fn(const VoxelKey&) for the 13 of the 26 neighbours of `key` that come after it in z,
/// then y, then x order (those inside the key space): walking every voxel of a set this way
/// visits each touching pair once.
template <class Fn>
void forEachLaterNeighbour(const VoxelKey& key, Fn&& fn) {
  for (int dz = 0; dz <= 1; ++dz) {
    for (int dy = dz == 0 ? 0 : -1; dy <= 1; ++dy) {
      for (int dx = (dz == 0 && dy == 0) ? 1 : -1; dx <= 1; ++dx) {
        if (const auto k = offsetKey(key, dx, dy, dz)) fn(*k);
      }
    }
  }
}

/// Calls pred(const VoxelKey&) for every key within Chebyshev distance r of `key` (itself
/// included) that lies inside the key space, until it returns true.
/// @return whether pred returned true for one of them.
template <class Pred>
bool anyKeyWithin(const VoxelKey& key, int r, Pred&& pred) {
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const auto k = offsetKey(key, dx, dy, dz);
        if (k && pred(*k)) return true;
      }
    }
  }
  return false;
}

/// Converts between metric coordinates (map frame) and voxel keys for one resolution.
/// Voxel k spans [(k - 2^15) * res, (k - 2^15 + 1) * res) on each axis.
class KeyGrid {
 public:
  /// @throw UsageError if resolution_m lies outside [kMinResolution_m, kMaxResolution_m].
  explicit KeyGrid(double resolution_m);

  double resolution_m() const { return resolution_m_; }
  /// Half the extent of the map along each axis, in metres.
  double halfExtent_m() const { return resolution_m_ * kKeyOrigin; }

  /// Continuous key-space coordinate (units of voxels) of a metric coordinate.
  Eigen::Vector3d toKeySpace(const Eigen::Vector3d& p_m) const {
    return p_m * inv_resolution_ + Eigen::Vector3d::Constant(kKeyOrigin);
  }
  /// The key of the voxel that contains p_m, or nothing if p_m lies outside the map.
  /// (Inline: it runs for every point of every frame.)
  std::optional<VoxelKey> keyOf(const Eigen::Vector3d& p_m) const {
    const Eigen::Vector3d u = toKeySpace(p_m);
    // floor(u) lies in [0, kKeysPerAxis) exactly when u does (false for NaN), and then equals
    // the truncation.
    for (int a = 0; a < 3; ++a) {
      if (!(u[a] >= 0.0 && u[a] < kKeysPerAxis)) return std::nullopt;
    }
    const auto axis = [&](int a) { return static_cast<uint16_t>(static_cast<int32_t>(u[a])); };
    return VoxelKey{axis(0), axis(1), axis(2)};
  }
  /// Centre of a voxel at the given level (0 = unit voxel) whose lower corner key is `key`.
  Eigen::Vector3d centerOf(const VoxelKey& key, int level = 0) const {
    const double half = 0.5 * static_cast<double>(1 << level);
    return cornerOf(key) + Eigen::Vector3d::Constant(half * resolution_m_);
  }
  /// Lower corner of the voxel `key`.
  Eigen::Vector3d cornerOf(const VoxelKey& key) const {
    return Eigen::Vector3d(static_cast<double>(key.x) - kKeyOrigin, static_cast<double>(key.y) - kKeyOrigin,
                           static_cast<double>(key.z) - kKeyOrigin) *
           resolution_m_;
  }

 private:
  double resolution_m_;
  double inv_resolution_;
};

}  // namespace chronomap
