#pragma once
/// @file
/// The voxels around a point that may lie within a radius of it (align/register.cpp).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "chronomap/core/key.h"
#include "chronomap/core/voxel_table.h"

namespace chronomap {

/// Calls fn(key) for the voxels of the cube of ceil(radius_voxels) voxels around the voxel of `p`
/// (inside the key space; z, then y, then x ascending) that may come within `radius_voxels` of
/// `p`: those whose centre (`box` false) or box (`box` true) comes within the radius, with a
/// margin for rounding (1e-6 of the squared radius). Every voxel it leaves out lies farther: a
/// filter before exact tests (the registration's neighbourhoods), which then keep their results
/// and their order while most of the cube, outside the ball, is never looked up.
/// @return false when `p` lies outside the grid (and fn is never called).
template <typename Fn>
bool forEachKeyWithin(const KeyGrid& grid, const Eigen::Vector3d& p, double radius_voxels, bool box, Fn fn) {
  const auto k = grid.keyOf(p);
  if (!k) return false;
  const int r = static_cast<int>(std::ceil(radius_voxels));
  const double res = grid.resolution_m();
  const double reach2 = radius_voxels * res * radius_voxels * res * (1.0 + 1e-6);
  const double slack = box ? 0.5 * res : 0.0;
  // p relative to its voxel's centre; voxel (dx, dy, dz) then lies at d * res - delta from p.
  const Eigen::Vector3d delta = p - grid.centerOf(*k);
  const auto gap2 = [&](int d, int axis) {
    const double g = std::max(0.0, std::abs(d * res - delta[axis]) - slack);
    return g * g;
  };
  for (int dz = -r; dz <= r; ++dz) {
    const double gz = gap2(dz, 2);
    if (gz > reach2) continue;
    for (int dy = -r; dy <= r; ++dy) {
      const double gzy = gz + gap2(dy, 1);
      if (gzy > reach2) continue;
      for (int dx = -r; dx <= r; ++dx) {
        if (gzy + gap2(dx, 0) > reach2) continue;
        if (const auto n = offsetKey(*k, dx, dy, dz)) fn(*n);
      }
    }
  }
  return true;
}

/// forEachKeyWithin() with lookups in `table`: calls fn(key, value) for the visited voxels that
/// `keep(key)` accepts and `table` holds, in the same order, as looking each up in turn would.
/// The table's slots for a batch of them are prefetched before they are looked up: in a table
/// larger than the cache the lookups then wait on memory together instead of one after another.
/// @return false when `p` lies outside the grid (and fn is never called).
template <typename V, typename Keep, typename Fn>
bool forEachFoundWithin(const VoxelTable<V>& table, const KeyGrid& grid, const Eigen::Vector3d& p,
                        double radius_voxels, bool box, Keep keep, Fn fn) {
  constexpr size_t kBatch = 32;
  std::array<VoxelKey, kBatch> keys;
  std::array<uint64_t, kBatch> codes;
  size_t n = 0;
  const auto lookUp = [&] {
    for (size_t j = 0; j < n; ++j) {
      if (const V* value = table.find(codes[j])) fn(keys[j], *value);
    }
    n = 0;
  };
  const bool inside = forEachKeyWithin(grid, p, radius_voxels, box, [&](const VoxelKey& key) {
    if (!keep(key)) return;
    keys[n] = key;
    codes[n] = mortonEncode(key);
    table.prefetch(codes[n]);
    if (++n == kBatch) lookUp();
  });
  lookUp();
  return inside;
}

}  // namespace chronomap
