#include "chronomap/temporal/window.h"

#include <algorithm>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

/// Appends to `out` the entries a window over sessions [first, last] holds of a list of `size`
/// entries whose first comes at or before `last`: the entry valid at `first` (as session 0, or
/// numbered from `first` when it comes after it), then the list's entries up to `last`.
void appendWindowEntries(const TemporalMap::Entry* list, size_t size, uint32_t first, uint32_t last,
                         std::vector<TemporalMap::Entry>& out) {
  size_t k = 0;
  while (k + 1 < size && list[k + 1].session <= first) ++k;
  out.push_back({list[k].session <= first ? 0u : list[k].session - first, list[k].value});
  for (++k; k < size && list[k].session <= last; ++k) out.push_back({list[k].session - first, list[k].value});
}

}  // namespace

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
    const size_t before = entries.size();
    if (list[0].session > last) {  // first observed after the window: its first entry alone
      entries.push_back({list[0].session - first, list[0].value});
      end = std::max(end, list[0].session);
    } else {
      appendWindowEntries(list, size, first, last, entries);
    }
    size = static_cast<uint32_t>(entries.size() - before);
  }
  parts.entries = std::move(entries);
  std::vector<SessionRecord> records(map.sessions().begin() + first, map.sessions().begin() + end + 1);
  for (SessionRecord& r : records) r.coverage = Coverage::fromRanges({});
  return TemporalMap::fromParts(map.resolution_m(), map.criterion(), std::move(parts), std::move(records));
}

namespace {

/// The window of `whole` (map's parts) over its sessions [first, last], session `first` a carried
/// one (its coverage left out) when `carried`: lists first observed after `last` left out, with
/// the inner nodes that then hold nothing; the rest numbered in the order they had.
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
    const size_t before = parts.entries.size();
    appendWindowEntries(list, size, first, last, parts.entries);
    new_list[i] = static_cast<uint32_t>(parts.list_sizes.size());
    parts.list_sizes.push_back(static_cast<uint32_t>(parts.entries.size() - before));
  }
  // The inner nodes kept, in their order: the root, those that still hold a list below them,
  // and those that held none in `map` either (a removed session leaves such nodes behind, and
  // the map keeps them); a node whose lists all came later goes.
  std::vector<uint8_t> holds(whole.inner.size(), 0);
  struct Below {
    bool had = false, has = false;  // a list below it in `map`; one in the window
  };
  auto mark = [&](auto&& self, uint32_t node) -> Below {
    Below b;
    for (const uint32_t r : whole.inner[node]) {
      if (r == TemporalMap::kEmpty) continue;
      if ((r & TemporalMap::kListBit) != 0) {
        b.had = true;
        b.has = b.has || new_list[r & ~TemporalMap::kListBit] != TemporalMap::kEmpty;
      } else {
        const Below c = self(self, r);
        b.had = b.had || c.had;
        b.has = b.has || c.has;
      }
    }
    holds[node] = node == 0 || b.has || !b.had;
    return b;
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

std::vector<TemporalMap> windowsOf(const TemporalMap& map, uint32_t k, uint32_t first_k) {
  if (k == 0) throw UsageError("windows of 0 sessions");
  if (first_k == 0) first_k = k;
  const size_t n = map.sessionCount();
  if (n == 0) throw UsageError("a 4D map that holds no session has no windows");
  const TemporalMap::Parts whole = map.parts();
  std::vector<TemporalMap> out;
  for (size_t start = 0, length = first_k; start < n; start += length, length = k) {
    const auto last = static_cast<uint32_t>(std::min(n, start + length) - 1);
    out.push_back(start == 0 ? windowBetween(map, whole, 0, last, false)
                             : windowBetween(map, whole, static_cast<uint32_t>(start - 1), last, true));
  }
  return out;
}

TemporalMap continuedWindow(const TemporalMap& map) {
  if (map.sessionCount() == 0) throw UsageError("a window cannot continue a 4D map that holds no session");
  TemporalMap window = historyWindow(map, static_cast<uint32_t>(map.sessionCount() - 1), 1);
  window.compact();  // lists whose carried states are free alike merge: the tree follows the place now
  return window;
}

namespace {

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
  std::span<const TemporalMap::Entry> list(uint32_t i) const {
    return {parts.entries.data() + begin[i], parts.entries.data() + begin[i + 1]};
  }
};

/// What one window holds at a cube: an inner node, a list (there or `above` levels higher), or
/// nothing.
struct Held {
  uint32_t ref = TemporalMap::kEmpty;
  int above = 0;
  bool isInner() const { return ref != TemporalMap::kEmpty && (ref & TemporalMap::kListBit) == 0; }
  bool isList() const { return ref != TemporalMap::kEmpty && (ref & TemporalMap::kListBit) != 0; }
};

/// Joins windows into one map's parts: the union of their trees, each list's entries from every
/// window in turn.
class Joiner {
 public:
  Joiner(const std::vector<TemporalMap>& windows, std::vector<uint32_t> base)
      : windows_(windows), base_(std::move(base)) {
    parts_.reserve(windows.size());
    for (const TemporalMap& w : windows) parts_.emplace_back(w);
  }

  TemporalMap::Parts join() {
    std::vector<Held> root(windows_.size(), Held{0, 0});
    below(root, kTreeDepth, VoxelKey{});
    return std::move(out_);
  }

 private:
  /// The union's node for the cube (corner, level) that `held` describes per window.
  uint32_t below(const std::vector<Held>& held, int level, const VoxelKey& corner) {
    const bool inner = level == kTreeDepth || std::any_of(held.begin(), held.end(), [](const Held& h) { return h.isInner(); });
    if (inner) {
      const auto node = static_cast<uint32_t>(out_.inner.size());
      out_.inner.emplace_back();
      out_.inner.back().fill(TemporalMap::kEmpty);
      std::vector<Held> child(held.size());
      for (int slot = 0; slot < 8; ++slot) {
        for (size_t j = 0; j < held.size(); ++j) {
          const Held& h = held[j];
          child[j] = h.isInner() ? Held{parts_[j].parts.inner[h.ref][slot], 0}
                     : h.isList() ? Held{h.ref, h.above + 1}
                                  : Held{};
        }
        const uint32_t r = below(child, level - 1, childCorner(corner, slot, level - 1));
        out_.inner[node][slot] = r;
      }
      return node;
    }
    if (std::none_of(held.begin(), held.end(), [](const Held& h) { return h.isList(); })) return TemporalMap::kEmpty;
    const size_t start = out_.entries.size();
    for (size_t j = 0; j < held.size(); ++j) {
      const bool before = out_.entries.size() > start;
      if (!held[j].isList()) {
        if (before) fail(j, corner, level, "a cube observed before it is missing from it");
        continue;
      }
      const std::span<const TemporalMap::Entry> list = parts_[j].list(held[j].ref & ~TemporalMap::kListBit);
      if (j > 0 && before != (list.front().session == 0)) {
        fail(j, corner, level,
             before ? "it carries no state into a cube observed before it"
                    : "it carries a state into a cube that no window before it observed");
      }
      for (size_t k = 0; k < list.size(); ++k) {
        TemporalMap::Entry e = list[k];
        for (int l = 0; l < held[j].above; ++l) e.value.length_m /= 8.0f;  // as TemporalMap::refine splits
        if (j > 0 && e.session == 0) {
          if (!carries(out_.entries.back().value, e.value)) {
            fail(j, corner, level, "its first session does not carry the state the windows before it end with");
          }
          continue;
        }
        if (j > 0) e.session = base_[j] + e.session - 1;
        out_.entries.push_back(e);
      }
    }
    out_.list_sizes.push_back(static_cast<uint32_t>(out_.entries.size() - start));
    return static_cast<uint32_t>(out_.list_sizes.size() - 1) | TemporalMap::kListBit;
  }

  /// True when `carried` is what a continued window carries of the state `last`: the same, or,
  /// where both are free without hits, another length (a cube the window merged, split again).
  static bool carries(const VoxelCounters& last, const VoxelCounters& carried) {
    if (last == carried) return true;
    VoxelCounters other = carried;
    other.length_m = last.length_m;
    return last.hits == 0 && last.length_m > 0.0f && carried.length_m > 0.0f && other == last;
  }

  [[noreturn]] static void fail(size_t window, const VoxelKey& corner, int level, const std::string& what) {
    throw FormatError("windows do not join: window " + std::to_string(window) + ", the cube at (" +
                      std::to_string(corner.x) + ", " + std::to_string(corner.y) + ", " + std::to_string(corner.z) +
                      ") of level " + std::to_string(level) + ": " + what);
  }

  const std::vector<TemporalMap>& windows_;
  std::vector<uint32_t> base_;
  std::vector<WindowParts> parts_;
  TemporalMap::Parts out_;
};

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
  TemporalMap::Parts parts = Joiner(windows, std::move(base)).join();
  return TemporalMap::fromParts(first.resolution_m(), first.criterion(), std::move(parts), std::move(records));
}

}  // namespace chronomap
