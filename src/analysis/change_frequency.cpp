#include "chronomap/analysis/change_frequency.h"

#include <algorithm>
#include <numeric>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

void countInto(std::vector<uint64_t>& histogram, int level, uint32_t n) {
  if (histogram.size() <= n) histogram.resize(n + 1, 0);
  histogram[n] += uint64_t{1} << (3 * level);
}

}  // namespace

uint64_t ChangeFrequency::changedVoxels() const {
  return std::accumulate(histogram.begin(), histogram.end(), uint64_t{0});
}

std::vector<uint64_t> changeHistogram(const TemporalMap& map, double from_s, double to_s) {
  std::vector<uint64_t> histogram;
  map.forEachChangeCount(from_s, to_s, [&](const VoxelKey&, int level, uint32_t n) { countInto(histogram, level, n); });
  return histogram;
}

ChangeFrequency changeFrequency(const TemporalMap& map, double from_s, double to_s, uint32_t min_changes) {
  if (min_changes < 1) throw UsageError("the least number of changes must be at least 1");
  if (to_s < from_s) throw UsageError("the end of the interval lies before its start");
  ChangeFrequency out;
  map.forEachChangeCount(from_s, to_s, [&](const VoxelKey& k, int level, uint32_t n) {
    countInto(out.histogram, level, n);
    if (n < min_changes) return;
    out.max_count = std::max(out.max_count, n);
    const int side = 1 << level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          out.voxels.push_back({VoxelKey{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy),
                                         static_cast<uint16_t>(k.z + dz)},
                                n});
        }
      }
    }
  });
  return out;
}

}  // namespace chronomap
