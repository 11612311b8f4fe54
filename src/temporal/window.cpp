#include "chronomap/temporal/window.h"

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/core/error.h"

namespace chronomap {

TemporalMap historyWindow(const TemporalMap& map, uint32_t first, uint32_t count) {
  return historyWindow(map, map.parts(), first, count);
}

TemporalMap historyWindow(const TemporalMap& map, const TemporalMap::Parts& whole, uint32_t first, uint32_t count) {
  const size_t sessions = map.sessionCount();
  if (count == 0 || first >= sessions || count > sessions - first) {
    throw UsageError("history window of sessions " + std::to_string(first) + " to " +
                     std::to_string(uint64_t{first} + count) + " does not lie inside the map's " +
                     std::to_string(sessions) + " sessions");
  }
  const uint32_t last = first + count - 1;
  TemporalMap::Parts parts{whole.inner, whole.list_sizes, {}};
  std::vector<TemporalMap::Entry> entries;
  entries.reserve(parts.list_sizes.size() * 2);
  uint32_t end = last;  // the last session the window holds
  size_t at = 0;
  for (uint32_t& size : parts.list_sizes) {
    const TemporalMap::Entry* list = whole.entries.data() + at;
    at += size;
    // The entry valid at `first` (the last one at or before it), if any, then those of the window.
    size_t k = 0;
    while (k + 1 < size && list[k + 1].session <= first) ++k;
    const size_t before = entries.size();
    if (list[k].session > last) {  // first observed after the window: its first entry alone
      entries.push_back({list[k].session - first, list[k].value});
      end = std::max(end, list[k].session);
    } else {
      entries.push_back({list[k].session <= first ? 0u : list[k].session - first, list[k].value});
      for (++k; k < size && list[k].session <= last; ++k) entries.push_back({list[k].session - first, list[k].value});
    }
    size = static_cast<uint32_t>(entries.size() - before);
  }
  parts.entries = std::move(entries);
  std::vector<SessionRecord> records(map.sessions().begin() + first, map.sessions().begin() + end + 1);
  for (SessionRecord& r : records) r.coverage = Coverage::fromRanges({});
  return TemporalMap::fromParts(map.resolution_m(), map.criterion(), std::move(parts), std::move(records));
}

}  // namespace chronomap
