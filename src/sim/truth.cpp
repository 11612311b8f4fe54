// The ground truth: the scene voxelised per session and per change event, and scoreOccupancy.
#include "chronomap/sim/truth.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "internal.h"

namespace chronomap {

namespace {

// Sorts keys in Morton order and drops repeats: the codes are computed once per key, not per
// comparison (the order is the same: a key's code is unique to it).
void sortMortonUnique(std::vector<VoxelKey>& keys) {
  std::vector<std::pair<uint64_t, VoxelKey>> coded(keys.size());
  for (size_t i = 0; i < keys.size(); ++i) coded[i] = {mortonEncode(keys[i]), keys[i]};
  std::sort(coded.begin(), coded.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  keys.clear();
  for (size_t i = 0; i < coded.size(); ++i) {
    if (i == 0 || coded[i].first != coded[i - 1].first) keys.push_back(coded[i].second);
  }
}

}  // namespace

std::vector<VoxelKey> objectVoxels(const Object& object, const KeyGrid& grid) {
  std::vector<VoxelKey> keys;
  if (!object.present) return keys;
  const double res = grid.resolution_m();
  auto index = [&](double v) { return static_cast<int64_t>(std::floor(v / res)) + kKeyOrigin; };
  // Last voxel index touched by [lo, hi): a face that ends on a voxel face does not enter it.
  auto lastIndex = [&](double hi) { return static_cast<int64_t>(std::ceil(hi / res)) - 1 + kKeyOrigin; };
  // Parts are solid: every voxel that overlaps one holds geometry (a wall's or a box's inside
  // is occupied space, even though no sensor sees it).
  for (const Part& p : object.parts) {
    const Eigen::Vector3d lo = p.box.min(), hi = p.box.max();
    int64_t first[3], last[3];
    for (int a = 0; a < 3; ++a) {
      first[a] = std::max<int64_t>(0, index(lo[a]));
      last[a] = std::min<int64_t>(kKeysPerAxis - 1, lastIndex(hi[a]));
    }
    for (int64_t z = first[2]; z <= last[2]; ++z) {
      for (int64_t y = first[1]; y <= last[1]; ++y) {
        for (int64_t x = first[0]; x <= last[0]; ++x) {
          keys.push_back(VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)});
        }
      }
    }
  }
  sortMortonUnique(keys);
  return keys;
}

std::vector<VoxelKey> truthOccupancy(const SceneState& state, const KeyGrid& grid) {
  std::vector<VoxelKey> all;
  for (const Object& o : state.objects) {
    const auto k = objectVoxels(o, grid);
    all.insert(all.end(), k.begin(), k.end());
  }
  sortMortonUnique(all);
  return all;
}

OccupancyScore scoreOccupancy(const SessionMap& map, const std::vector<VoxelKey>& truth) {
  OccupancyScore s;
  map.forEachLeaf([&](const LeafView& leaf) {
    if (leaf.level == 0 && leaf.counters.state() == VoxelState::Occupied) {
      ++s.predicted;
      if (std::binary_search(truth.begin(), truth.end(), leaf.key, [](const VoxelKey& a, const VoxelKey& b) {
            return mortonEncode(a) < mortonEncode(b);
          })) {
        ++s.true_positive;
      }
    }
  });
  for (const VoxelKey& k : truth) {
    if (map.stateOf(k) != VoxelState::Unknown) ++s.truth_known;
  }
  s.precision = s.predicted ? static_cast<double>(s.true_positive) / static_cast<double>(s.predicted) : 0.0;
  s.recall = s.truth_known ? static_cast<double>(s.true_positive) / static_cast<double>(s.truth_known) : 0.0;
  return s;
}

namespace sim_detail {

namespace {

bool containsKey(const std::vector<VoxelKey>& sorted, const VoxelKey& k) {
  return std::binary_search(sorted.begin(), sorted.end(), k,
                            [](const VoxelKey& a, const VoxelKey& b) { return mortonEncode(a) < mortonEncode(b); });
}

}  // namespace

ChangeEvent changeEvent(uint32_t id, EventKind kind, const SceneState& previous_state, const SceneState& state,
                        const std::vector<VoxelKey>& previous_truth, const std::vector<VoxelKey>& truth,
                        const KeyGrid& grid) {
  const Object* before = nullptr;
  const Object* after = nullptr;
  for (const Object& o : previous_state.objects) {
    if (o.id == id) before = &o;
  }
  for (const Object& o : state.objects) {
    if (o.id == id) after = &o;
  }
  std::vector<VoxelKey> candidates;
  if (before) candidates = objectVoxels(*before, grid);
  if (after) {
    const auto v = objectVoxels(*after, grid);
    candidates.insert(candidates.end(), v.begin(), v.end());
  }
  ChangeEvent e;
  e.object = id;
  e.object_kind = after ? after->kind : before->kind;
  e.kind = kind;
  for (const VoxelKey& k : candidates) {
    if (containsKey(previous_truth, k) != containsKey(truth, k)) e.voxels.push_back(k);
  }
  std::sort(e.voxels.begin(), e.voxels.end());
  e.voxels.erase(std::unique(e.voxels.begin(), e.voxels.end()), e.voxels.end());
  return e;
}

SessionMap truthMap(const std::vector<VoxelKey>& truth, const KeyGrid& grid) {
  SessionMap occupancy(grid.resolution_m());
  VoxelCounters occupied;
  occupied.hits = 1;
  std::vector<VoxelCounters> values(truth.size(), occupied);
  occupancy.addMany(truth, values);
  return occupancy;
}

}  // namespace sim_detail

}  // namespace chronomap
