#include "chronomap/temporal/window.h"

#include <algorithm>
#include <array>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/core/tree_walk.h"

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

namespace {

/// The window of `whole` (map's parts) over its sessions [first, last], carried at `first` when
/// `carried`: lists first observed after `last` left out, with the inner nodes that then hold
/// nothing; the rest numbered in the order they had.
TemporalMap windowBetween(const TemporalMap& map, const TemporalMap::Parts& whole, uint32_t first, uint32_t last,
                          bool carried) {
  const size_t lists = whole.list_sizes.size();
  std::vector<uint32_t> new_list(lists, TemporalMap::kEmpty);
  TemporalMap::Parts parts;
  parts.entries.reserve(whole.entries.size());
  size_t at = 0;
  for (size_t i = 0; i < lists; ++i) {
    const TemporalMap::Entry* list = whole.entries.data() + at;
    const uint32_t size = whole.list_sizes[i];
    at += size;
    if (list[0].session > last) continue;  // first observed after the window
    size_t k = 0;
    while (k + 1 < size && list[k + 1].session <= first) ++k;  // the entry valid at `first`
    const size_t before = parts.entries.size();
    if (carried) {
      parts.entries.push_back({list[k].session <= first ? 0u : list[k].session - first, list[k].value});
      ++k;
    }
    for (; k < size && list[k].session <= last; ++k) parts.entries.push_back({list[k].session - first, list[k].value});
    new_list[i] = static_cast<uint32_t>(parts.list_sizes.size());
    parts.list_sizes.push_back(static_cast<uint32_t>(parts.entries.size() - before));
  }
  // The inner nodes that still hold a list below them (the root always), in their order.
  std::vector<uint8_t> holds(whole.inner.size(), 0);
  auto mark = [&](auto&& self, uint32_t node) -> bool {
    bool any = node == 0;
    for (const uint32_t r : whole.inner[node]) {
      if (r == TemporalMap::kEmpty) continue;
      if ((r & TemporalMap::kListBit) != 0) {
        any = any || new_list[r & ~TemporalMap::kListBit] != TemporalMap::kEmpty;
      } else {
        any = self(self, r) || any;
      }
    }
    holds[node] = any;
    return any;
  };
  mark(mark, 0);
  std::vector<uint32_t> new_inner(whole.inner.size(), TemporalMap::kEmpty);
  for (size_t i = 0; i < whole.inner.size(); ++i) {
    if (!holds[i]) continue;
    new_inner[i] = static_cast<uint32_t>(parts.inner.size());
    parts.inner.emplace_back();
  }
  for (size_t i = 0; i < whole.inner.size(); ++i) {
    if (!holds[i]) continue;
    for (int c = 0; c < 8; ++c) {
      const uint32_t r = whole.inner[i][c];
      uint32_t& out = parts.inner[new_inner[i]][c];
      if (r == TemporalMap::kEmpty) {
        out = TemporalMap::kEmpty;
      } else if ((r & TemporalMap::kListBit) != 0) {
        const uint32_t l = new_list[r & ~TemporalMap::kListBit];
        out = l == TemporalMap::kEmpty ? TemporalMap::kEmpty : l | TemporalMap::kListBit;
      } else {
        out = new_inner[r];  // kEmpty when nothing below it is left
      }
    }
  }
  std::vector<SessionRecord> records(map.sessions().begin() + first, map.sessions().begin() + last + 1);
  if (carried) records.front().coverage = Coverage::fromRanges({});
  return TemporalMap::fromParts(map.resolution_m(), map.criterion(), std::move(parts), std::move(records));
}

}  // namespace

std::vector<TemporalMap> windowsOf(const TemporalMap& map, uint32_t k) {
  if (k == 0) throw UsageError("windows of 0 sessions");
  const size_t n = map.sessionCount();
  if (n == 0) throw UsageError("a 4D map that holds no session has no windows");
  const TemporalMap::Parts whole = map.parts();
  std::vector<TemporalMap> out;
  for (size_t start = 0; start < n; start += k) {
    const auto last = static_cast<uint32_t>(std::min(n, start + k) - 1);
    out.push_back(start == 0 ? windowBetween(map, whole, 0, last, false)
                             : windowBetween(map, whole, static_cast<uint32_t>(start - 1), last, true));
  }
  return out;
}

TemporalMap continuedWindow(const TemporalMap& map) {
  if (map.sessionCount() == 0) throw UsageError("a window cannot continue a 4D map that holds no session");
  return historyWindow(map, static_cast<uint32_t>(map.sessionCount() - 1), 1);
}

namespace {

using Entries = std::vector<TemporalMap::Entry>;

/// One window's parts, with where each list's entries begin.
struct WindowParts {
  TemporalMap::Parts parts;
  std::vector<size_t> begin;

  explicit WindowParts(const TemporalMap& w) : parts(w.parts()) {
    begin.reserve(parts.list_sizes.size() + 1);
    size_t at = 0;
    for (const uint32_t n : parts.list_sizes) {
      begin.push_back(at);
      at += n;
    }
    begin.push_back(at);
  }
  void appendList(uint32_t list, Entries& out) const {
    out.insert(out.end(), parts.entries.begin() + static_cast<std::ptrdiff_t>(begin[list]),
               parts.entries.begin() + static_cast<std::ptrdiff_t>(begin[list + 1]));
  }
};

[[noreturn]] void failJoin(size_t window, const VoxelKey& corner, int level, const std::string& what) {
  throw FormatError("windows do not join: window " + std::to_string(window) + ", the cube at (" +
                    std::to_string(corner.x) + ", " + std::to_string(corner.y) + ", " + std::to_string(corner.z) +
                    ") of level " + std::to_string(level) + ": " + what);
}

/// The entries of inner node `node` (a cube at `level`) merged as compaction merges them: its
/// children merged first, then the eight lists' lengths summed per entry by sumOfEight.
void mergedBelow(const WindowParts& w, size_t window, uint32_t node, int level, const VoxelKey& corner, Entries& out) {
  std::array<Entries, 8> child;
  for (int i = 0; i < 8; ++i) {
    const uint32_t r = w.parts.inner[node][i];
    const VoxelKey k = childCorner(corner, i, level - 1);
    if (r == TemporalMap::kEmpty) failJoin(window, k, level - 1, "a later window merged a cube that this one did not observe whole");
    if ((r & TemporalMap::kListBit) != 0) {
      w.appendList(r & ~TemporalMap::kListBit, child[i]);
    } else {
      mergedBelow(w, window, r, level - 1, k, child[i]);
    }
    for (const TemporalMap::Entry& e : child[i]) {
      if (!(e.value.length_m > 0.0f && e.value.hits == 0)) {
        failJoin(window, k, level - 1, "a later window merged a cube that this one holds as not free");
      }
    }
    if (child[i].size() != child[0].size() ||
        !std::equal(child[i].begin(), child[i].end(), child[0].begin(),
                    [](const auto& a, const auto& b) { return a.session == b.session; })) {
      failJoin(window, corner, level, "a later window merged lists that this one holds on different sessions");
    }
  }
  out = child[0];
  for (size_t k = 0; k < out.size(); ++k) {
    float lengths[8];
    for (int i = 0; i < 8; ++i) lengths[i] = child[i][k].value.length_m;
    out[k].value.length_m = TemporalMap::sumOfEight(lengths);
  }
}

/// The entries window `w` holds for the cube (corner, level), in its own session numbers: a
/// list there, a coarser list's split as refinements split it, or the merge of a finer subtree.
void entriesAt(const WindowParts& w, size_t window, const VoxelKey& corner, int level, Entries& out) {
  out.clear();
  uint32_t node = 0;
  for (int child_level = kTreeDepth - 1; child_level >= level; --child_level) {
    const uint32_t r = w.parts.inner[node][childSlot(corner, child_level)];
    if (r == TemporalMap::kEmpty) return;
    if ((r & TemporalMap::kListBit) != 0) {
      w.appendList(r & ~TemporalMap::kListBit, out);
      for (int l = child_level; l > level; --l) {
        for (TemporalMap::Entry& e : out) e.value.length_m /= 8.0f;  // as TemporalMap::refine splits
      }
      return;
    }
    if (child_level == level) {
      mergedBelow(w, window, r, level, corner, out);
      return;
    }
    node = r;
  }
}

}  // namespace

TemporalMap joinWindows(const std::vector<TemporalMap>& windows) {
  if (windows.empty()) throw UsageError("no windows to join");
  const TemporalMap& first = windows.front();
  std::vector<SessionRecord> records;
  std::vector<uint32_t> base(windows.size(), 0);  // global rank of each window's first own session
  for (size_t j = 0; j < windows.size(); ++j) {
    const TemporalMap& w = windows[j];
    if (w.resolution_m() != first.resolution_m() || !(w.criterion() == first.criterion())) {
      throw UsageError("window " + std::to_string(j) + " differs from window 0 in resolution or change criterion");
    }
    if (j > 0) {
      if (w.sessionCount() == 0 || windows[j - 1].sessionCount() == 0 ||
          w.sessions().front().time_s != windows[j - 1].sessions().back().time_s) {
        throw UsageError("window " + std::to_string(j) + " does not continue window " + std::to_string(j - 1) +
                         " (its first session is not the last one before it)");
      }
    }
    base[j] = static_cast<uint32_t>(records.size());
    records.insert(records.end(), w.sessions().begin() + (j > 0 ? 1 : 0), w.sessions().end());
  }
  std::vector<WindowParts> parts;
  parts.reserve(windows.size());
  for (const TemporalMap& w : windows) parts.emplace_back(w);
  const TemporalMap::Parts& last = parts.back().parts;
  const size_t lists = last.list_sizes.size();
  std::vector<VoxelKey> corner(lists);
  std::vector<int> level(lists, -1);
  walkPoolTree(
      last.inner, TemporalMap::kListBit, [](uint32_t) { return true; },
      [&](uint32_t r, const VoxelKey& k, int l) {
        const uint32_t i = r & ~TemporalMap::kListBit;
        if (i >= lists) throw FormatError("windows do not join: the last window's tree refers to a list it does not hold");
        corner[i] = k;
        level[i] = l;
      });
  TemporalMap::Parts out{last.inner, {}, {}};
  out.list_sizes.reserve(lists);
  out.entries.reserve(last.entries.size() * 2);
  Entries scratch;
  for (size_t i = 0; i < lists; ++i) {
    if (level[i] < 0) throw FormatError("windows do not join: the last window's tree does not reach every list");
    const size_t start = out.entries.size();
    for (size_t j = 0; j < windows.size(); ++j) {
      entriesAt(parts[j], j, corner[i], level[i], scratch);
      const bool before = out.entries.size() > start;
      if (j > 0 && before) {
        // A continued window carries the state before it as its session 0: the same value.
        if (scratch.empty() || scratch.front().session != 0 || !(scratch.front().value == out.entries.back().value)) {
          failJoin(j, corner[i], level[i], "its first session does not carry the state the windows before it end with");
        }
      }
      for (TemporalMap::Entry e : scratch) {
        if (j > 0) {
          if (e.session == 0) continue;
          e.session = base[j] + e.session - 1;
        }
        out.entries.push_back(e);
      }
    }
    if (out.entries.size() == start) failJoin(windows.size() - 1, corner[i], level[i], "no window holds an entry for this list");
    out.list_sizes.push_back(static_cast<uint32_t>(out.entries.size() - start));
  }
  return TemporalMap::fromParts(first.resolution_m(), first.criterion(), std::move(out), std::move(records));
}

}  // namespace chronomap
