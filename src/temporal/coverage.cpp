#include "chronomap/temporal/coverage.h"

#include <algorithm>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {
constexpr uint64_t kMortonEnd = uint64_t{1} << (3 * kTreeDepth);
}

Coverage::Coverage(const SessionMap& map) {
  map.forEachLeaf([&](const LeafView& leaf) {
    const uint64_t begin = mortonEncode(leaf.key);
    const uint64_t end = begin + (uint64_t{1} << (3 * leaf.level));
    if (!ranges_.empty() && ranges_.back() == begin) {
      ranges_.back() = end;  // leaves come in Morton order: extend the current run
    } else {
      ranges_.push_back(begin);
      ranges_.push_back(end);
    }
  });
  ranges_.shrink_to_fit();
}

Coverage Coverage::fromRanges(std::vector<uint64_t> pairs) {
  if (pairs.size() % 2 != 0) throw FormatError("coverage has an odd number of range bounds");
  uint64_t previous_end = 0;
  for (size_t i = 0; i < pairs.size(); i += 2) {
    const uint64_t b = pairs[i], e = pairs[i + 1];
    if (b >= e || e > kMortonEnd || (i > 0 && b <= previous_end)) {
      throw FormatError("coverage ranges are not sorted, disjoint and inside the map");
    }
    previous_end = e;
  }
  Coverage c;
  c.ranges_ = std::move(pairs);
  return c;
}

Coverage::Overlap Coverage::overlap(const VoxelKey& corner, int level) const {
  const uint64_t begin = mortonEncode(corner);
  const uint64_t end = begin + (uint64_t{1} << (3 * level));
  // The first range whose end lies after `begin`.
  const size_t n = ranges_.size() / 2;
  size_t lo = 0, hi = n;
  while (lo < hi) {
    const size_t mid = (lo + hi) / 2;
    if (ranges_[2 * mid + 1] <= begin) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  if (lo == n || ranges_[2 * lo] >= end) return Overlap::None;
  if (ranges_[2 * lo] <= begin && ranges_[2 * lo + 1] >= end) return Overlap::Full;
  return Overlap::Partial;
}

uint64_t Coverage::voxelCount() const {
  uint64_t n = 0;
  for (size_t i = 0; i < ranges_.size(); i += 2) n += ranges_[i + 1] - ranges_[i];
  return n;
}

}  // namespace chronomap
