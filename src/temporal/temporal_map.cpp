// TemporalMap: sessions added and removed, snapshots, histories, compaction and files' parts.
// Its pools, coarse entries and layout have their own files (pools.cpp, coarse.cpp, layout.cpp).
#include "chronomap/temporal/temporal_map.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/offset_quantiser.h"
#include "chronomap/core/time.h"
#include "pool_limits.h"

namespace chronomap {

using temporal_detail::kMaxIndex;
using temporal_detail::kMaxListSize;

namespace {

// Counters of one of the 8 children of a uniform cube. Lists above unit level only ever hold
// known-free counters without hits, so only the length is split; a power-of-two division of a
// float is exact.
VoxelCounters eighth(const VoxelCounters& c) {
  VoxelCounters part = c;
  part.length_m /= 8.0f;
  return part;
}

/// Refuses what the evidence rule cannot do exactly (ChangeCriterion::hasEvidenceRule): `what`
/// says what was asked.
[[noreturn]] void refuseOutOfOrder(const std::string& what) {
  throw UsageError("this 4D map's change criterion has the evidence rule (--min-free-length, --min-hits), which "
                   "takes sessions in time order only: " + what);
}

}  // namespace

bool ChangeCriterion::differs(const VoxelCounters& before, const VoxelCounters& after) const {
  const VoxelState was = before.state(), now = after.state();
  if (was != now) {
    if (was == VoxelState::Occupied && now == VoxelState::Free && after.hits == 0 &&
        static_cast<double>(after.length_m) < min_free_length_m) {
      return false;  // grazed, not seen through
    }
    if (was == VoxelState::Free && now == VoxelState::Occupied && after.hits < min_hits) return false;  // stray
    return true;
  }
  if (probability_threshold > 0.0 && std::abs(before.probability() - after.probability()) > probability_threshold) {
    return true;
  }
  if (colour_distance > 0.0 && before.hits > 0 && after.hits > 0) {
    const Rgb a = before.meanColour(), b = after.meanColour();
    const double dr = a.r - b.r, dg = a.g - b.g, db = a.b - b.b;
    if (std::sqrt(dr * dr + dg * dg + db * db) > colour_distance) return true;
  }
  if (surface_shift_voxels > 0.0 && before.hits > 0 && after.hits > 0 && before.hits >= min_hits &&
      after.hits >= min_hits) {
    double d2 = 0.0;
    for (int axis = 0; axis < 3; ++axis) d2 += std::pow(after.meanOffset(axis) - before.meanOffset(axis), 2);
    if (d2 > surface_shift_voxels * surface_shift_voxels) return true;
  }
  return false;
}

void ChangeCriterion::validate() const {
  if (!std::isfinite(probability_threshold) || probability_threshold < 0.0 || probability_threshold >= 1.0) {
    throw UsageError("probability threshold must lie in [0, 1), got " + std::to_string(probability_threshold));
  }
  if (!std::isfinite(colour_distance) || colour_distance < 0.0) {
    throw UsageError("colour distance must be a non-negative number, got " + std::to_string(colour_distance));
  }
  if (!(min_free_length_m >= 0.0) || !std::isfinite(min_free_length_m)) {
    throw UsageError("minimum free length must be a non-negative number of metres, got " +
                     std::to_string(min_free_length_m));
  }
  if (min_hits > 1000000) throw UsageError("minimum hits must lie in [0, 1000000], got " + std::to_string(min_hits));
  if (!(surface_shift_voxels >= 0.0 && surface_shift_voxels <= 2.0)) {
    throw UsageError("surface shift must lie in [0, 2] voxels, got " + std::to_string(surface_shift_voxels));
  }
}

TemporalMap::TemporalMap(double resolution_m, ChangeCriterion criterion) : grid_(resolution_m), criterion_(criterion) {
  criterion_.validate();
  if (criterion_.min_hits == 1) criterion_.min_hits = 0;  // the same rule (off), stored the same way
  inner_.emplace_back();
  inner_[0].fill(kEmpty);
  coarse_span_.emplace_back();
  coarse_dirty_.push_back(1);
}

VoxelCounters TemporalMap::valueOf(const Stored& s) const {
  VoxelCounters v;
  v.length_m = s.length_m;
  if (s.part == kNoPart) return v;
  const HitPart& p = hit_parts_[s.part];
  v.hits = p.hits;
  v.red = p.red;
  v.green = p.green;
  v.blue = p.blue;
  if (p.hits > 0) {
    for (int a = 0; a < 3; ++a) v.offset[a] = dequantiseOffset(p.offset[a], p.hits);
  }
  return v;
}

std::span<const TemporalMap::Entry> TemporalMap::decoded(const List& l, std::vector<Entry>& scratch) const {
  scratch.resize(l.size);
  const Stored* e = entriesOf(l);
  for (size_t i = 0; i < l.size; ++i) scratch[i] = entryOf(e[i]);
  return {scratch.data(), scratch.size()};
}

size_t TemporalMap::lowerBound(const List& l, uint32_t session) const {
  const Stored* e = entriesOf(l);
  size_t i = 0;
  while (i < l.size && e[i].session < session) ++i;  // lists are short: a linear scan wins
  return i;
}

uint32_t TemporalMap::refine(uint32_t node, int slot) {
  const uint32_t list = index(inner_[node][slot]);
  coarse_dirty_[node] = 1;
  const uint32_t child = newInner();
  std::vector<Entry> history;
  decoded(lists_[list], history);
  for (Entry& e : history) e.value = eighth(e.value);
  for (int i = 0; i < 8; ++i) {
    const uint32_t l = newList(store(history[0].session, history[0].value));
    for (size_t k = 1; k < history.size(); ++k) insertEntry(l, k, store(history[k].session, history[k].value));
    inner_[child][i] = l | kListBit;
  }
  freeList(list);
  inner_[node][slot] = child;
  return child;
}

std::optional<std::pair<uint32_t, CoverageIndex::Overlap>> TemporalMap::nextObserver(uint32_t rank,
                                                                                     const VoxelKey& corner, int level) {
  if (coverage_cache_.size() != sessions_.size()) {
    coverage_cache_.clear();
    coverage_cache_.resize(sessions_.size());
  }
  for (uint32_t s = rank + 1; s < sessions_.size(); ++s) {
    if (!coverage_cache_[s]) coverage_cache_[s] = std::make_shared<const CoverageIndex>(sessions_[s].coverage);
    const CoverageIndex::Overlap o = coverage_cache_[s]->overlap(corner, level);
    if (o != CoverageIndex::Overlap::None) return std::make_pair(s, o);
  }
  return std::nullopt;
}

void TemporalMap::apply(uint32_t node, int level, const VoxelKey& corner, int target_level,
                        const VoxelCounters& value, uint32_t rank, AddReport& report) {
  // The path down to here, for markPath(); restored however this returns.
  struct Restore {
    std::vector<uint32_t>& path;
    size_t size;
    ~Restore() { path.resize(size); }
  } restore{path_, path_.size()};
  while (true) {
    path_.push_back(node);
    const int child_level = level - 1;
    const int slot = childSlot(corner, child_level);
    const Ref r = inner_[node][slot];
    if (child_level > target_level) {
      if (r == kEmpty) {
        const uint32_t child = newInner();
        ++report.inner_added;
        inner_[node][slot] = child;
        markPath();
        node = child;
      } else if (isInner(r)) {
        node = r;
      } else {
        // A uniform cube larger than the observation: refine only when the state changes.
        const List& l = lists_[index(r)];
        const size_t pos = lowerBound(l, rank);
        if (pos > 0 && !criterion_.differs(valueOf(entriesOf(l)[pos - 1]), value)) return;
        markPath();
        node = refine(node, slot);
        report.inner_added += 1;
      }
      level = child_level;
      continue;
    }
    // The slot is the observed cube itself.
    if (r == kEmpty) {
      // Nobody observed any of this cube before, so no later session did either.
      inner_[node][slot] = newList(store(rank, value)) | kListBit;
      ++report.entries_added;
      markPath();
      return;
    }
    if (isList(r)) {
      applyToList(node, slot, child_level, corner, value, rank, report);
      return;
    }
    // The session saw a uniform cube where the map holds finer structure: each eighth.
    const VoxelCounters part = eighth(value);
    for (int i = 0; i < 8; ++i) {
      apply(r, child_level, childCorner(corner, i, child_level - 1), child_level - 1, part, rank, report);
    }
    return;
  }
}

void TemporalMap::applyToList(uint32_t node, int slot, int level, const VoxelKey& corner,
                              const VoxelCounters& value, uint32_t rank, AddReport& report) {
  const uint32_t list = index(inner_[node][slot]);
  const size_t pos = lowerBound(lists_[list], rank);
  std::optional<VoxelCounters> before;
  if (pos > 0) before = valueOf(entriesOf(lists_[list])[pos - 1]);
  if (before && !criterion_.differs(*before, value)) return;  // no change: nothing to store
  coarse_dirty_[node] = 1;  // `node` may lie below path_ (a cube refined here)
  markPath();

  const auto next = nextObserver(rank, corner, level);
  if (next && next->second == CoverageIndex::Overlap::Partial && level > 0) {
    // A later session saw only part of the cube: its parts now have different histories.
    const uint32_t child = refine(node, slot);
    ++report.inner_added;
    const VoxelCounters part = eighth(value);
    for (int i = 0; i < 8; ++i) {
      applyToList(child, i, level - 1, childCorner(corner, i, level - 1), part, rank, report);
    }
    return;
  }
  insertEntry(list, pos, store(rank, value));
  ++report.entries_added;
  if (!next) return;
  // The next observer's entry was decided against `before`; decide it again against `value`.
  const List& l = lists_[list];
  const size_t j = pos + 1;
  if (j < l.size && entriesOf(l)[j].session == next->first) {
    if (!criterion_.differs(value, valueOf(entriesOf(l)[j]))) {
      eraseEntry(list, j);
      ++report.entries_removed;
    }
  } else if (before) {
    // It confirmed `before` and was not stored; with `value` in between it is a change back.
    insertEntry(list, j, store(next->first, *before));
    ++report.entries_added;
  }
}

void TemporalMap::shiftSessions(uint32_t from, int delta) {
  markAllCoarseDirty();
  auto shift = [&](Stored& e) {
    if (e.session >= from) e.session = static_cast<uint32_t>(static_cast<int64_t>(e.session) + delta);
  };
  for (List& l : lists_) {
    if (l.size == 0) continue;
    Stored* e = entriesOf(l);
    for (size_t i = 0; i < l.size; ++i) shift(e[i]);
    if (l.size >= 2) l.first = e[l.size - 1];
  }
}

std::optional<uint32_t> TemporalMap::rankAtOrBefore(double time_s) const {
  const auto it = std::upper_bound(sessions_.begin(), sessions_.end(), time_s + kTimeSlack_s,
                                   [](double t, const SessionRecord& s) { return t < s.time_s; });
  if (it == sessions_.begin()) return std::nullopt;
  return static_cast<uint32_t>(it - sessions_.begin() - 1);
}

AddReport TemporalMap::add(double time_s, const SessionMap& session, const AddSettings& options) {
  checkTime(time_s, "session time " + exactNumber(time_s));
  compact_ = false;
  if (session.resolution_m() != resolution_m()) {
    throw UsageError("session resolution " + std::to_string(session.resolution_m()) +
                     " m differs from the 4D map's " + std::to_string(resolution_m()) + " m");
  }
  AddReport report;
  auto it = std::lower_bound(sessions_.begin(), sessions_.end(), time_s,
                             [](const SessionRecord& s, double t) { return s.time_s < t; });
  if (it != sessions_.end() && it->time_s == time_s) {
    if (options.replace && criterion_.hasEvidenceRule() && it + 1 != sessions_.end()) {
      refuseOutOfOrder("only its last session can be replaced");
    }
    if (!options.replace) {
      throw UsageError("the 4D map already holds a session at " + formatTime(time_s) +
                       " (ask to replace it, or give another time)");
    }
    remove(time_s);
    report.replaced = true;
    it = std::lower_bound(sessions_.begin(), sessions_.end(), time_s,
                          [](const SessionRecord& s, double t) { return s.time_s < t; });
  }
  const auto rank = static_cast<uint32_t>(it - sessions_.begin());
  report.out_of_order = rank < sessions_.size();
  if (report.out_of_order && criterion_.hasEvidenceRule()) {
    refuseOutOfOrder(formatTime(time_s) + " is before its last session (" + formatTime(sessions_.back().time_s) + ")");
  }
  if (report.out_of_order) shiftSessions(rank, +1);
  SessionRecord record;
  record.time_s = time_s;
  record.name = options.name;
  record.nodes_separate = session.innerCount() + session.leafCount();
  record.coverage = Coverage(session);
  sessions_.insert(sessions_.begin() + rank, std::move(record));

  const size_t nodes_before = inner_.size() + live_entries_;
  coverage_cache_.clear();
  change_masks_valid_ = false;
  session.forEachLeaf([&](const LeafView& leaf) {
    apply(0, kTreeDepth, leaf.key, leaf.level, leaf.counters, rank, report);
  });
  coverage_cache_.clear();
  updateCoarse();
  sessions_[rank].nodes_added = static_cast<int64_t>(inner_.size() + live_entries_) - static_cast<int64_t>(nodes_before);
  relayoutIfScattered();
  return report;
}

void TemporalMap::appendUnobservedSessions(const std::vector<SessionRecord>& later) {
  compact_ = false;
  double last = sessions_.empty() ? -std::numeric_limits<double>::infinity() : sessions_.back().time_s;
  for (const SessionRecord& s : later) {
    if (!std::isfinite(s.time_s) || !(s.time_s > last)) {
      throw UsageError("an unobserved session at " + formatTime(s.time_s) + " is not after the map's last session");
    }
    last = s.time_s;
  }
  sessions_.reserve(sessions_.size() + later.size());
  for (const SessionRecord& s : later) {
    SessionRecord r;
    r.time_s = s.time_s;
    r.name = s.name;
    r.coverage = Coverage::fromRanges({});
    sessions_.push_back(std::move(r));
  }
  // No entry names the new ranks: the lists, coarse intervals (open-ended ones stay open) and
  // the change summary read the same; only the coverage cache is indexed by rank.
  coverage_cache_.clear();
}

void TemporalMap::replaceSessionRecords(std::vector<SessionRecord> records) {
  if (records.size() != sessions_.size()) {
    throw UsageError(std::to_string(records.size()) + " session records given for a map of " +
                     std::to_string(sessions_.size()) + " sessions");
  }
  for (size_t i = 0; i < records.size(); ++i) {
    if (records[i].time_s != sessions_[i].time_s) {
      throw UsageError("session record " + std::to_string(i) + " is at " + formatTime(records[i].time_s) +
                       ", not at the map's " + formatTime(sessions_[i].time_s));
    }
  }
  sessions_ = std::move(records);
  coverage_cache_.clear();
  compact_ = false;
}

void TemporalMap::remove(double time_s) {
  compact_ = false;
  auto it = std::lower_bound(sessions_.begin(), sessions_.end(), time_s,
                             [](const SessionRecord& s, double t) { return s.time_s < t; });
  if (it == sessions_.end() || it->time_s != time_s) {
    throw UsageError("the 4D map holds no session at " + formatTime(time_s));
  }
  const auto rank = static_cast<uint32_t>(it - sessions_.begin());
  if (criterion_.hasEvidenceRule() && rank + 1 != sessions_.size()) {
    refuseOutOfOrder("only its last session can be removed");
  }
  coverage_cache_.clear();
  change_masks_valid_ = false;
  removeBelow(0, kTreeDepth, VoxelKey{}, rank);
  coverage_cache_.clear();
  sessions_.erase(sessions_.begin() + rank);
  shiftSessions(rank + 1, -1);
  updateCoarse();
  relayoutIfScattered();
}

void TemporalMap::removeBelow(uint32_t node, int level, const VoxelKey& base, uint32_t rank) {
  coarse_dirty_[node] = 1;
  for (int slot = 0; slot < 8; ++slot) {
    const Ref r = inner_[node][slot];
    if (r == kEmpty) continue;
    const VoxelKey corner = childCorner(base, slot, level - 1);
    if (isInner(r)) {
      removeBelow(r, level - 1, corner, rank);
    } else {
      removeFromList(node, slot, level - 1, corner, rank);
    }
  }
}

void TemporalMap::removeFromList(uint32_t node, int slot, int level, const VoxelKey& corner, uint32_t rank) {
  coarse_dirty_[node] = 1;
  const uint32_t list = index(inner_[node][slot]);
  const size_t pos = lowerBound(lists_[list], rank);
  if (pos >= lists_[list].size || entriesOf(lists_[list])[pos].session != rank) return;
  const auto next = nextObserver(rank, corner, level);
  if (next && next->second == CoverageIndex::Overlap::Partial && level > 0) {
    const uint32_t child = refine(node, slot);
    for (int i = 0; i < 8; ++i) removeFromList(child, i, level - 1, childCorner(corner, i, level - 1), rank);
    return;
  }
  const VoxelCounters removed = valueOf(entriesOf(lists_[list])[pos]);
  std::optional<VoxelCounters> before;
  if (pos > 0) before = valueOf(entriesOf(lists_[list])[pos - 1]);
  eraseEntry(list, pos);
  if (next) {
    const List& l = lists_[list];
    if (pos < l.size && entriesOf(l)[pos].session == next->first) {
      if (before && !criterion_.differs(*before, valueOf(entriesOf(l)[pos]))) eraseEntry(list, pos);
    } else if (!before || criterion_.differs(*before, removed)) {
      // The next observer confirmed the removed state without being stored: it now carries it.
      insertEntry(list, pos, store(next->first, removed));
    }
  }
  if (lists_[list].size == 0) {
    freeList(list);
    inner_[node][slot] = kEmpty;
  }
}

std::vector<double> TemporalMap::times() const {
  std::vector<double> t;
  t.reserve(sessions_.size());
  for (const auto& s : sessions_) t.push_back(s.time_s);
  return t;
}

template <class CoarseFn, class ListFn>
void TemporalMap::copyTree(const std::vector<Children>& tree, CoarseFn&& coarse, ListFn&& list, size_t reserve_inner,
                           size_t reserve_leaves, SessionMap& out, SnapshotVisits& seen) {
  std::vector<SessionMap::Children> inner;
  std::vector<VoxelCounters> leaves;
  inner.reserve(reserve_inner);
  leaves.reserve(reserve_leaves);
  auto leaf = [&](const VoxelCounters& v) {
    leaves.push_back(v);
    return static_cast<uint32_t>(leaves.size() - 1) | SessionMap::kLeafBit;
  };
  auto build = [&](auto&& self, uint32_t node) -> SessionMap::Ref {
    const auto me = static_cast<uint32_t>(inner.size());
    inner.emplace_back();
    ++seen.inner;
    bool any = false;
    for (int slot = 0; slot < 8; ++slot) {
      const Ref r = tree[node][slot];
      SessionMap::Ref out_ref = SessionMap::kEmpty;
      if (isInner(r)) {
        if (const std::optional<float> length = coarse(r)) {
          // The whole cube reads free without hits: one leaf, as compressFree() makes it.
          VoxelCounters v;
          v.length_m = *length;
          out_ref = leaf(v);
          ++seen.coarse;
        } else {
          out_ref = self(self, r);
        }
      } else if (isList(r)) {
        ++seen.lists;
        leaves.emplace_back();
        if (list(r, leaves.back())) {
          out_ref = static_cast<uint32_t>(leaves.size() - 1) | SessionMap::kLeafBit;
        } else {
          leaves.pop_back();
        }
      }
      inner[me][slot] = out_ref;
      any = any || out_ref != SessionMap::kEmpty;
    }
    if (!any && me != 0) {
      inner.pop_back();
      return SessionMap::kEmpty;
    }
    return me;
  };
  build(build, 0);
  out.adoptPools(std::move(inner), std::move(leaves));
}

SessionMap TemporalMap::snapshot(double time_s, SnapshotVisits* visits) const {
  SnapshotVisits seen;
  if (visits) *visits = seen;
  SessionMap out(resolution_m());
  const auto rank = rankAtOrBefore(time_s);
  if (!rank) return out;
  const uint32_t last = *rank;
  auto coarse = [&](Ref r) -> std::optional<float> {
    if (const Coarse* c = coarseAt(r, last)) return c->length_m;
    return std::nullopt;
  };
  auto list = [&](Ref r, VoxelCounters& v) {
    const List& l = lists_[index(r)];
    // The newest entry is valid: it is kept in the list record itself, so the snapshot of the
    // latest time never reads the entry arena.
    if (l.first.session <= last) {
      v = valueOf(l.first);
      return true;
    }
    if (l.size <= 1 || entriesOf(l)[0].session > last) return false;
    // An older entry: binary search, so that long histories do not slow snapshots down.
    const Stored* e = entriesOf(l);
    size_t lo = 1, hi = l.size - 1;  // e[lo - 1] <= last < e[hi]
    while (lo < hi) {
      const size_t mid = (lo + hi) / 2;
      if (e[mid].session <= last) {
        lo = mid + 1;
      } else {
        hi = mid;
      }
    }
    v = valueOf(e[lo - 1]);
    return true;
  };
  copyTree(inner_, coarse, list, inner_.size(), live_lists_, out, seen);
  if (visits) *visits = seen;
  return out;
}

SessionMap TemporalMap::snapshotOfStates(double resolution_m, const std::vector<Children>& inner_in,
                                         const std::vector<std::optional<VoxelCounters>>& valid) {
  SessionMap out(resolution_m);
  const std::vector<int> list_level = listLevelsOf(inner_in, valid.size());
  for (size_t i = 0; i < valid.size(); ++i) {
    if (!valid[i]) continue;
    if (!std::isfinite(valid[i]->length_m) || valid[i]->length_m < 0.0f) {
      throw FormatError("4D map has an invalid ray length");
    }
    if (!valid[i]->offsetsValid()) throw FormatError("4D map has an invalid hit position");
    if (list_level[i] > 0 && !valid[i]->isKnownFreeWithoutHits()) {
      throw FormatError("4D map has a uniform cube that is not known-free");
    }
  }
  // As store() then valueOf() give it: no part without hits or colour, offsets quantised.
  auto stored = [](const VoxelCounters& c) {
    VoxelCounters v;
    v.length_m = c.length_m;
    if (c.hits == 0 && c.red == 0 && c.green == 0 && c.blue == 0) return v;
    v.hits = c.hits;
    v.red = c.red;
    v.green = c.green;
    v.blue = c.blue;
    if (c.hits > 0) {
      for (int a = 0; a < 3; ++a) v.offset[a] = dequantiseOffset(quantiseOffset(c.offset[a], c.hits), c.hits);
    }
    return v;
  };
  auto listAt = [&](Ref r) -> const std::optional<VoxelCounters>& { return valid[index(r)]; };
  // The coarse entry of every inner node valid now (rebuildCoarse's intervals at this one rank):
  // all 8 children read free without hits, lengths summed in slot order. Bottom up; -1: none.
  std::vector<float> coarse(inner_in.size(), -1.0f);
  auto coarseOf = [&](auto&& self, uint32_t node) -> void {
    bool all = node != 0;  // the root is never one leaf
    float sum = 0.0f;
    for (const Ref r : inner_in[node]) {
      if (isInner(r)) {
        self(self, r);
        if (coarse[r] < 0.0f) all = false;
        else sum += coarse[r];
      } else if (isList(r)) {
        const auto& v = listAt(r);
        if (!v || !(v->length_m > 0.0f) || v->hits != 0) all = false;
        else sum += v->length_m;
      } else {
        all = false;
      }
    }
    if (all) coarse[node] = sum;
  };
  coarseOf(coarseOf, 0);
  SnapshotVisits seen;
  copyTree(
      inner_in, [&](Ref r) -> std::optional<float> { return coarse[r] >= 0.0f ? std::optional<float>(coarse[r]) : std::nullopt; },
      [&](Ref r, VoxelCounters& out_v) {
        const auto& v = listAt(r);
        if (v) out_v = stored(*v);
        return v.has_value();
      },
      0, 0, out, seen);
  return out;
}

std::vector<HistoryEntry> TemporalMap::history(const VoxelKey& key) const {
  std::vector<HistoryEntry> h;
  uint32_t node = 0;
  for (int level = kTreeDepth - 1; level >= 0; --level) {
    const Ref r = inner_[node][childSlot(key, level)];
    if (r == kEmpty) return h;
    if (isInner(r)) {
      node = r;
      continue;
    }
    const List& l = lists_[index(r)];
    const Stored* e = entriesOf(l);
    h.reserve(l.size);
    const auto scale = static_cast<float>(uint64_t{1} << (3 * level));
    for (size_t i = 0; i < l.size; ++i) {
      VoxelCounters c = valueOf(e[i]);
      if (level > 0) c.length_m /= scale;
      h.push_back(HistoryEntry{sessions_[e[i].session].time_s, c, level});
    }
    return h;
  }
  return h;
}

std::optional<VoxelCounters> TemporalMap::valueAt(const VoxelKey& key, double time_s) const {
  const auto rank = rankAtOrBefore(time_s);
  if (!rank) return std::nullopt;
  std::optional<VoxelCounters> value;
  for (const HistoryEntry& e : history(key)) {
    if (e.time_s > sessions_[*rank].time_s) break;
    value = e.counters;
  }
  return value;
}

TemporalCounts TemporalMap::counts() const {
  TemporalCounts c;
  c.inner_nodes = inner_.size();
  c.slots = live_lists_;
  c.entries = live_entries_;
  return c;
}

size_t TemporalMap::sessionBytes() const {
  size_t bytes = 0;
  for (const auto& s : sessions_) bytes += s.coverage.memoryBytes() + sizeof(SessionRecord) + s.name.capacity();
  return bytes;
}

size_t TemporalMap::memoryBytes() const {
  // memoryUse() splits the same sum part by part (walking the lists); this stays constant time.
  return inner_.size() * sizeof(Children) + lists_.size() * sizeof(List) + arena_.size() * sizeof(Stored) +
         hit_parts_.size() * sizeof(HitPart) + free_hit_parts_.capacity() * sizeof(uint32_t) + coarseBytes() +
         sessionBytes() + change_masks_.capacity() * sizeof(uint64_t);
}

TemporalMap::MemoryUse TemporalMap::memoryUse() const {
  MemoryUse m;
  m.inner = inner_.size() * sizeof(Children);
  m.lists = live_lists_ * sizeof(List);
  for (const List& l : lists_) {
    if (l.size < 2) continue;
    m.entries += l.size * sizeof(Stored);
  }
  m.hit_parts = (hit_parts_.size() - free_hit_parts_.size()) * sizeof(HitPart);
  m.slack = arena_.size() * sizeof(Stored) - m.entries + (lists_.size() - live_lists_) * sizeof(List) +
            free_hit_parts_.size() * sizeof(HitPart) + free_hit_parts_.capacity() * sizeof(uint32_t);
  m.coarse = coarseBytes();
  m.sessions = sessionBytes();
  m.change_masks = change_masks_.capacity() * sizeof(uint64_t);
  return m;
}

bool TemporalMap::compactBelow(Ref& r, int level) {
  // Returns true when `r` is (now) a list without hits, candidate for merging one level up.
  if (r == kEmpty) return false;
  if (isList(r)) {
    const List& l = lists_[index(r)];
    const Stored* e = entriesOf(l);
    for (size_t i = 0; i < l.size; ++i) {
      if (!freeWithoutHits(e[i])) return false;
    }
    return true;
  }
  bool mergeable = true;
  for (int i = 0; i < 8; ++i) {
    Ref child = inner_[r][i];
    mergeable = compactBelow(child, level - 1) && mergeable;
    inner_[r][i] = child;
  }
  if (!mergeable || r == 0) return false;
  // Same sessions in all 8 lists: then every voxel of the cube read free at the same times.
  const List& first = lists_[index(inner_[r][0])];
  for (int i = 1; i < 8; ++i) {
    const List& other = lists_[index(inner_[r][i])];
    if (other.size != first.size) return false;
    for (size_t k = 0; k < first.size; ++k) {
      if (entriesOf(other)[k].session != entriesOf(first)[k].session) return false;
    }
  }
  const uint32_t keep = index(inner_[r][0]);
  for (int i = 1; i < 8; ++i) {
    const uint32_t other = index(inner_[r][i]);
    for (size_t k = 0; k < first.size; ++k) {
      entriesOf(lists_[keep])[k].length_m += entriesOf(lists_[other])[k].length_m;
    }
    freeList(other);
  }
  List& merged = lists_[keep];
  if (merged.size >= 2) merged.first = entriesOf(merged)[merged.size - 1];
  r = keep | kListBit;  // the inner node becomes garbage that the re-layout drops
  return true;
}

void TemporalMap::buildChangeMasks() const {
  change_masks_.assign(inner_.size(), 0);
  auto build = [&](auto&& self, uint32_t node) -> uint64_t {
    uint64_t mask = 0;
    for (const Ref r : inner_[node]) {
      if (isInner(r)) {
        mask |= self(self, r);
      } else if (isList(r)) {
        const List& l = lists_[index(r)];
        const Stored* e = entriesOf(l);
        for (size_t i = 1; i < l.size; ++i) mask |= uint64_t{1} << (e[i].session % 64);
      }
    }
    change_masks_[node] = mask;
    return mask;
  };
  build(build, 0);
  change_masks_valid_ = true;
}

size_t TemporalMap::compact(Relayout relayout) {
  if (compact_) return 0;
  const size_t lists_before = live_lists_;
  change_masks_valid_ = false;
  Ref root = 0;
  compactBelow(root, kTreeDepth);
  if (relayout == Relayout::kWhenMerged && live_lists_ == lists_before) {
    // Nothing merged: the tree is as it was, its coarse entries still hold.
    compact_ = true;
    return 0;
  }
  Parts p = parts();
  const size_t relayouts = relayouts_;
  *this = fromParts(resolution_m(), criterion_, std::move(p), std::move(sessions_));
  relayouts_ = relayouts + 1;
  compact_ = true;
  return lists_before - live_lists_;
}

std::vector<int> TemporalMap::listLevelsOf(const std::vector<Children>& inner, size_t lists) {
  if (inner.empty()) throw FormatError("4D map has no root node");
  if (inner.size() >= kMaxIndex || lists >= kMaxIndex) throw FormatError("4D map too large");
  // Shape: every node reached once from the root, lists only, inner nodes above unit level.
  std::vector<uint8_t> inner_seen(inner.size(), 0), list_seen(lists, 0);
  std::vector<int> list_level(lists, 0);
  std::vector<std::pair<uint32_t, int>> stack{{0u, kTreeDepth}};
  inner_seen[0] = 1;
  size_t inner_reached = 1, lists_reached = 0;
  while (!stack.empty()) {
    auto [node, level] = stack.back();
    stack.pop_back();
    for (Ref r : inner[node]) {
      if (r == kEmpty) continue;
      const uint32_t i = index(r);
      if (isList(r)) {
        if (i >= lists || list_seen[i]) throw FormatError("4D map has an invalid list reference");
        list_seen[i] = 1;
        list_level[i] = level - 1;
        ++lists_reached;
      } else {
        if (level - 1 == 0) throw FormatError("4D map has an inner node below unit level");
        if (i >= inner.size() || inner_seen[i]) throw FormatError("4D map has an invalid node reference");
        inner_seen[i] = 1;
        ++inner_reached;
        stack.emplace_back(i, level - 1);
      }
    }
  }
  if (inner_reached != inner.size() || lists_reached != lists) throw FormatError("4D map has unreachable nodes");
  return list_level;
}

TemporalMap TemporalMap::fromParts(double resolution_m, ChangeCriterion criterion, Parts parts,
                                   std::vector<SessionRecord> sessions) {
  TemporalMap m(resolution_m, criterion);
  for (size_t i = 0; i < sessions.size(); ++i) {
    if (!std::isfinite(sessions[i].time_s) || (i > 0 && !(sessions[i - 1].time_s < sessions[i].time_s))) {
      throw FormatError("4D map session times are not finite and increasing");
    }
  }
  if (parts.inner.empty()) throw FormatError("4D map has no root node");
  if (parts.inner.size() >= kMaxIndex || parts.list_sizes.size() >= kMaxIndex) throw FormatError("4D map too large");
  uint64_t total = 0;
  for (uint32_t s : parts.list_sizes) {
    if (s == 0 || s > kMaxListSize) throw FormatError("4D map has a history list of impossible length");
    total += s;
  }
  if (total != parts.entries.size()) throw FormatError("4D map history lists do not match the entries stored");
  std::vector<uint64_t> offsets(parts.list_sizes.size());
  uint64_t at = 0;
  for (size_t i = 0; i < offsets.size(); ++i) {
    offsets[i] = at;
    at += parts.list_sizes[i];
  }
  const std::vector<int> list_level = listLevelsOf(parts.inner, parts.list_sizes.size());
  for (size_t i = 0; i < parts.list_sizes.size(); ++i) {
    for (uint64_t k = 0; k < parts.list_sizes[i]; ++k) {
      const Entry& e = parts.entries[offsets[i] + k];
      if (e.session >= sessions.size() || (k > 0 && e.session <= parts.entries[offsets[i] + k - 1].session)) {
        throw FormatError("4D map has a history entry with an invalid session");
      }
      if (!std::isfinite(e.value.length_m) || e.value.length_m < 0.0f) {
        throw FormatError("4D map has an invalid ray length");
      }
      if (!e.value.offsetsValid()) throw FormatError("4D map has an invalid hit position");
      if (list_level[i] > 0 && !e.value.isKnownFreeWithoutHits()) {
        throw FormatError("4D map has a uniform cube that is not known-free");
      }
    }
  }
  m.inner_ = std::move(parts.inner);
  m.coarse_span_.assign(m.inner_.size(), CoarseSpan{});
  m.coarse_dirty_.assign(m.inner_.size(), 1);
  // Each list's block at its final capacity (the one insertEntry's doubling reaches), and the
  // hit parts stored in the order packHitParts lays them out: every list's newest entry first,
  // in list order, then the older entries.
  m.lists_.resize(parts.list_sizes.size());
  m.hit_parts_.reserve(static_cast<size_t>(
      std::count_if(parts.entries.begin(), parts.entries.end(), [](const Entry& e) { return keepsHitPart(e.value); })));
  for (size_t i = 0; i < parts.list_sizes.size(); ++i) {
    const uint32_t n = parts.list_sizes[i];
    const Entry& newest = parts.entries[offsets[i] + n - 1];
    List& l = m.lists_[i];
    l.first = m.store(newest.session, newest.value);
    l.size = static_cast<uint16_t>(n);
    if (n >= 2) {
      const auto capacity_log2 = static_cast<uint8_t>(std::max(1u, std::bit_width(n - 1)));
      l.block = m.allocBlock(capacity_log2);
      l.capacity_log2 = capacity_log2;
      m.arena_[l.block + n - 1] = l.first;
    }
    ++m.live_lists_;
    m.live_entries_ += n;
  }
  for (size_t i = 0; i < parts.list_sizes.size(); ++i) {
    const Entry* e = parts.entries.data() + offsets[i];
    const List& l = m.lists_[i];
    for (uint32_t k = 0; k + 1 < l.size; ++k) m.arena_[l.block + k] = m.store(e[k].session, e[k].value);
  }
  m.sessions_ = std::move(sessions);
  m.updateCoarse();
  m.packCoarse();  // in node order, as the pools are laid out
  // Files hold the pools as relayout() lays them out: the latest snapshot's nodes first.
  const Layout hot = m.scatteredHot().second;
  m.hot_inner_at_layout_ = hot.hot_inner;
  m.hot_lists_at_layout_ = hot.hot_lists;
  return m;
}

bool operator==(const TemporalMap& a, const TemporalMap& b) {
  if (a.resolution_m() != b.resolution_m() || a.sessions_.size() != b.sessions_.size()) return false;
  if (!(a.criterion_ == b.criterion_)) return false;
  for (size_t i = 0; i < a.sessions_.size(); ++i) {
    const auto& x = a.sessions_[i];
    const auto& y = b.sessions_[i];
    if (x.time_s != y.time_s || x.name != y.name || x.nodes_separate != y.nodes_separate ||
        x.nodes_added != y.nodes_added || !(x.coverage == y.coverage)) {
      return false;
    }
  }
  const TemporalMap::Parts pa = a.parts(), pb = b.parts();
  return pa.inner == pb.inner && pa.list_sizes == pb.list_sizes && pa.entries == pb.entries;
}

}  // namespace chronomap
