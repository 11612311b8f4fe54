#include "chronomap/export/export.h"

#include <octomap/ColorOcTree.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/core/file.h"
#include "chronomap/octree/voxel_queries.h"

namespace chronomap {

size_t exportOccupiedPly(const std::filesystem::path& path, const SessionMap& map) {
  const VoxelCentres occupied = occupiedCentres(map);
  PointCloud cloud;
  cloud.points.reserve(occupied.centers_m.size());
  for (const Eigen::Vector3d& c : occupied.centers_m) cloud.points.push_back(c.cast<float>());
  cloud.colours = occupied.colours;
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  writePly(path, cloud);
  return cloud.points.size();
}

size_t exportOctomap(const std::filesystem::path& path, const SessionMap& map) {
  octomap::ColorOcTree tree(map.resolution_m());
  const double p_min = tree.getClampingThresMin();
  const double p_max = tree.getClampingThresMax();
  auto logodds = [&](double p) {
    p = std::clamp(p, p_min, p_max);
    return static_cast<float>(std::log(p / (1.0 - p)));
  };
  map.forEachLeaf([&](const LeafView& leaf) {
    const VoxelState state = leaf.counters.state();
    if (state == VoxelState::Unknown) return;
    const float value = logodds(leaf.counters.probability());
    const int side = 1 << leaf.level;
    const Rgb colour = leaf.counters.meanColour();
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          const octomap::OcTreeKey key(static_cast<octomap::key_type>(leaf.key.x + dx),
                                       static_cast<octomap::key_type>(leaf.key.y + dy),
                                       static_cast<octomap::key_type>(leaf.key.z + dz));
          tree.setNodeValue(key, value, true);
          if (state == VoxelState::Occupied) tree.setNodeColor(key, colour.r, colour.g, colour.b);
        }
      }
    }
  });
  tree.updateInnerOccupancy();
  tree.prune();
  // Through the same temporary file and rename as every writer: a full disk leaves the old file.
  std::ostringstream out;
  if (!tree.write(out)) throw IoError(path.string() + ": cannot encode the OctoMap tree");
  const std::string bytes = out.str();
  writeFileAtomic(path, std::vector<uint8_t>(bytes.begin(), bytes.end()));
  return tree.getNumLeafNodes();
}

size_t exportDiffPly(const std::filesystem::path& path, const DiffMap& diff, std::span<const ChangeCell> cells) {
  uint64_t total = 0;
  for (const ChangeCell& c : cells) total += uint64_t{1} << (3 * c.level);
  constexpr uint64_t kMaxPoints = 100'000'000;
  if (total > kMaxPoints) {
    throw DataError(path.string() + ": " + std::to_string(total) + " voxels are too many for a PLY cloud");
  }
  PointCloud cloud;
  for (const ChangeCell& c : cells) {
    const int side = 1 << c.level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          const VoxelKey k{static_cast<uint16_t>(c.key.x + dx), static_cast<uint16_t>(c.key.y + dy),
                           static_cast<uint16_t>(c.key.z + dz)};
          cloud.points.push_back(diff.grid().centerOf(k).cast<float>());
          cloud.colours.push_back(c.colour);
        }
      }
    }
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  writePly(path, cloud);
  return cloud.points.size();
}

}  // namespace chronomap
