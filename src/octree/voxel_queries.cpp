#include "chronomap/octree/voxel_queries.h"

namespace chronomap {

VoxelCentres occupiedCentres(const SessionMap& map) {
  VoxelCentres out;
  map.forEachLeaf([&](const LeafView& leaf) {
    if (leaf.level != 0 || leaf.counters.state() != VoxelState::Occupied) return;
    out.centers_m.push_back(map.grid().centerOf(leaf.key));
    out.colours.push_back(leaf.counters.meanColour());
  });
  return out;
}

FreeLeaves freeLeaves(const SessionMap& map) {
  FreeLeaves out;
  map.forEachLeaf([&](const LeafView& leaf) {
    if (leaf.counters.state() != VoxelState::Free) return;
    const double size = map.resolution_m() * static_cast<double>(1u << leaf.level);
    out.centers_m.push_back(map.grid().cornerOf(leaf.key) + Eigen::Vector3d::Constant(0.5 * size));
    out.sizes_m.push_back(size);
  });
  return out;
}

std::optional<Bounds> knownBounds(const SessionMap& map) {
  std::optional<Bounds> out;
  map.forEachLeaf([&](const LeafView& leaf) {
    const Eigen::Vector3d a = map.grid().cornerOf(leaf.key);
    const Eigen::Vector3d b = a + Eigen::Vector3d::Constant(map.resolution_m() * (1 << leaf.level));
    if (!out) {
      out = Bounds{a, b};
    } else {
      out->min_m = out->min_m.cwiseMin(a);
      out->max_m = out->max_m.cwiseMax(b);
    }
  });
  return out;
}

}  // namespace chronomap
