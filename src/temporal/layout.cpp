// TemporalMap's layout: the order of the pools that files hold and relayout() restores (what a
// snapshot of the latest time reads first), and when add() and remove() re-lay the pools out.
#include "chronomap/temporal/temporal_map.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace chronomap {

namespace {

// add() and remove() re-lay the pools out once the nodes that the latest snapshot reads outside
// the block where the last layout put them reach 1/kRelayoutShare of that snapshot's nodes (and
// at least kMinRelayout nodes). Each node read out of place costs about a cache miss: at 16 a
// snapshot of the latest time stayed within 1.15x of a freshly laid-out map's on
// bench/temporal's stress case (at 8: 1.4x), and add() took about 1.6x the processor time at
// 365 sessions (each re-layout costs about as much as copying the pools; docs/temporal.md).
constexpr size_t kRelayoutShare = 16;
constexpr size_t kMinRelayout = 1024;

}  // namespace

void TemporalMap::relayoutIfScattered() {
  const size_t scattered = scatteredHot().first;
  if (scattered >= std::max(kMinRelayout, (hot_inner_at_layout_ + hot_lists_at_layout_) / kRelayoutShare)) relayout();
}

std::pair<size_t, TemporalMap::Layout> TemporalMap::scatteredHot() const {
  // What the latest snapshot reads outside the block where the last layout put it: created
  // since, or moved out of the shadowed layer by a coarse entry that ended.
  const auto latest = static_cast<uint32_t>(sessions_.empty() ? 0 : sessions_.size() - 1);
  size_t scattered = 0;
  Layout hot;
  hot.hot_inner = 1;
  auto visit = [&](auto&& self, uint32_t node) -> void {
    for (const Ref r : inner_[node]) {
      if (r == kEmpty) continue;
      if (isList(r)) {
        scattered += index(r) >= hot_lists_at_layout_;
        ++hot.hot_lists;
      } else {
        scattered += r >= hot_inner_at_layout_;
        ++hot.hot_inner;
        if (!coarseAt(r, latest)) self(self, r);
      }
    }
  };
  visit(visit, 0);
  return {scattered, hot};
}

TemporalMap::Layout TemporalMap::layout() const {
  // Depth first, in two layers: first what a snapshot of the latest time reads, then the
  // subtrees that a coarse entry shadows at that time (each depth first), so that this
  // snapshot walks a dense prefix of the pools however much refined history lies behind it.
  // The root of a shadowed subtree stays in the first layer, where the snapshot reads its
  // coarse entry; only what lies below it is deferred.
  Layout order;
  order.inner.reserve(inner_.size());
  order.lists.reserve(live_lists_);
  const bool layered = !sessions_.empty();
  const auto latest = static_cast<uint32_t>(layered ? sessions_.size() - 1 : 0);
  std::vector<uint32_t> shadowed;
  auto visit = [&](auto&& self, uint32_t node, bool defer) -> void {
    for (const Ref r : inner_[node]) {
      if (r == kEmpty) continue;
      if (isList(r)) {
        order.lists.push_back(index(r));
      } else {
        order.inner.push_back(r);
        if (defer && coarseAt(r, latest)) {
          shadowed.push_back(r);
        } else {
          self(self, r, defer);
        }
      }
    }
  };
  order.inner.push_back(0);
  visit(visit, 0, layered);
  order.hot_inner = order.inner.size();
  order.hot_lists = order.lists.size();
  for (const uint32_t node : shadowed) visit(visit, node, false);
  return order;
}

void TemporalMap::relayout() {
  compact_ = false;
  const Layout order = layout();
  std::vector<uint32_t> new_inner(inner_.size(), kEmpty), new_list(lists_.size(), kEmpty);
  for (size_t i = 0; i < order.inner.size(); ++i) new_inner[order.inner[i]] = static_cast<uint32_t>(i);
  for (size_t i = 0; i < order.lists.size(); ++i) new_list[order.lists[i]] = static_cast<uint32_t>(i);
  std::vector<Children> inner(order.inner.size());
  std::vector<CoarseSpan> spans(order.inner.size());
  std::vector<uint8_t> dirty(order.inner.size());
  for (size_t i = 0; i < order.inner.size(); ++i) {
    const uint32_t old = order.inner[i];
    for (size_t slot = 0; slot < 8; ++slot) {
      const Ref r = inner_[old][slot];
      inner[i][slot] = r == kEmpty ? kEmpty : isList(r) ? new_list[index(r)] | kListBit : new_inner[r];
    }
    spans[i] = coarse_span_[old];
    dirty[i] = coarse_dirty_[old];
  }
  std::vector<List> lists(order.lists.size());
  for (size_t i = 0; i < order.lists.size(); ++i) lists[i] = lists_[order.lists[i]];
  packHitParts(lists);
  // Lists keep their blocks in the entry arena (a snapshot of the latest time does not read it).
  inner_ = std::move(inner);
  lists_ = std::move(lists);
  free_lists_.clear();
  coarse_span_ = std::move(spans);
  coarse_dirty_ = std::move(dirty);
  packCoarse();
  change_masks_valid_ = false;
  hot_inner_at_layout_ = order.hot_inner;
  hot_lists_at_layout_ = order.hot_lists;
  ++relayouts_;
}

void TemporalMap::packHitParts(std::vector<List>& lists) {
  // First the parts of the lists' newest entries in list order (what a snapshot of the latest
  // time reads, in the order it reads them), then the older entries' parts; free parts dropped.
  std::vector<HitPart> parts;
  parts.reserve(hit_parts_.size() - free_hit_parts_.size());
  auto move = [&](Stored& e) {
    if (e.part == kNoPart) return;
    parts.push_back(hit_parts_[e.part]);
    e.part = static_cast<uint32_t>(parts.size() - 1);
  };
  for (List& l : lists) {
    if (l.size == 0) continue;
    move(entriesOf(l)[l.size - 1]);
    if (l.size >= 2) l.first = entriesOf(l)[l.size - 1];
  }
  for (List& l : lists) {
    Stored* e = entriesOf(l);
    for (size_t k = 0; k + 1 < l.size; ++k) move(e[k]);
  }
  hit_parts_ = std::move(parts);
  free_hit_parts_.clear();
  free_hit_parts_.shrink_to_fit();
}

TemporalMap::Parts TemporalMap::parts() const {
  const Layout order = layout();
  std::vector<uint32_t> new_inner(inner_.size(), kEmpty), new_list(lists_.size(), kEmpty);
  for (size_t i = 0; i < order.inner.size(); ++i) new_inner[order.inner[i]] = static_cast<uint32_t>(i);
  for (size_t i = 0; i < order.lists.size(); ++i) new_list[order.lists[i]] = static_cast<uint32_t>(i);
  Parts p;
  p.inner.resize(order.inner.size());
  p.list_sizes.reserve(order.lists.size());
  p.entries.reserve(live_entries_);
  for (size_t i = 0; i < order.inner.size(); ++i) {
    for (size_t slot = 0; slot < 8; ++slot) {
      const Ref r = inner_[order.inner[i]][slot];
      p.inner[i][slot] = r == kEmpty ? kEmpty : isList(r) ? new_list[index(r)] | kListBit : new_inner[r];
    }
  }
  for (const uint32_t list : order.lists) {
    const List& l = lists_[list];
    p.list_sizes.push_back(l.size);
    const Stored* e = entriesOf(l);
    for (size_t i = 0; i < l.size; ++i) p.entries.push_back(entryOf(e[i]));
  }
  return p;
}

}  // namespace chronomap
