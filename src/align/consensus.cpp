#include "chronomap/align/consensus.h"

#include <algorithm>
#include <cmath>

#include "chronomap/core/error.h"

namespace chronomap {

SessionMap consensus(std::span<const SessionMap* const> maps) {
  if (maps.empty()) throw UsageError("consensus of no session maps");
  for (const SessionMap* m : maps) {
    if (m == nullptr) throw UsageError("consensus: a session map is missing");
    if (m->resolution_m() != maps.front()->resolution_m()) {
      throw UsageError("consensus: the session maps have different resolutions");
    }
  }
  SessionMap sum(maps.front()->resolution_m());
  for (const SessionMap* m : maps) sum.merge(*m);
  return sum;
}

SessionMap consensus(std::span<const SessionMap> maps) {
  std::vector<const SessionMap*> pointers;
  pointers.reserve(maps.size());
  for (const SessionMap& m : maps) pointers.push_back(&m);
  return consensus(std::span<const SessionMap* const>(pointers));
}

SessionMap consensus(const TemporalMap& map, double t0_s, double t1_s) {
  if (std::isnan(t0_s) || std::isnan(t1_s) || t0_s > t1_s) {
    throw UsageError("consensus: the time range is empty or not a number");
  }
  // Ranks of the sessions with a time in [t0, t1].
  const auto& sessions = map.sessions();
  const auto before = std::lower_bound(sessions.begin(), sessions.end(), t0_s,
                                       [](const SessionRecord& s, double t) { return s.time_s < t; });
  const uint32_t lo = static_cast<uint32_t>(before - sessions.begin());
  const uint32_t hi = map.ranksThrough(t1_s);
  SessionMap sum(map.resolution_m());
  if (lo >= hi) return sum;
  const uint32_t count = static_cast<uint32_t>(sessions.size());
  map.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
    for (size_t i = 0; i < entries.size(); ++i) {
      // Entry i is what the snapshots at ranks [from, to) read.
      const uint32_t from = std::max(entries[i].session, lo);
      const uint32_t to = std::min(i + 1 < entries.size() ? entries[i + 1].session : count, hi);
      if (from >= to) continue;
      const uint32_t w = to - from;
      VoxelCounters c = entries[i].value;
      c.length_m *= static_cast<float>(w);
      c.hits *= w;
      c.red *= w;
      c.green *= w;
      c.blue *= w;
      for (float& o : c.offset) o *= static_cast<float>(w);
      sum.addCube(corner, level, c);
    }
  });
  return sum;
}

}  // namespace chronomap
