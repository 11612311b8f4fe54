// TemporalMap's coarse entries (the versioned inner slots, temporal_map.h): recomputed bottom up
// for the nodes marked dirty, packed, and looked up by rank.
#include "chronomap/temporal/temporal_map.h"

#include <algorithm>
#include <array>

namespace chronomap {

size_t TemporalMap::coarseBytes() const {
  return coarse_.capacity() * sizeof(Coarse) + coarse_span_.capacity() * sizeof(CoarseSpan) + coarse_dirty_.capacity();
}

void TemporalMap::markPath() {
  for (const uint32_t node : path_) coarse_dirty_[node] = 1;
}

void TemporalMap::markAllCoarseDirty() { std::fill(coarse_dirty_.begin(), coarse_dirty_.end(), uint8_t{1}); }

void TemporalMap::updateCoarse() {
  rebuildCoarse(0);
  // Drop the garbage once it outweighs the live entries.
  if (coarse_garbage_ > 4096 && coarse_garbage_ > coarse_.size() / 2) packCoarse();
}

void TemporalMap::packCoarse() {
  std::vector<Coarse> live;
  live.reserve(coarse_.size() - coarse_garbage_);
  for (CoarseSpan& span : coarse_span_) {
    const auto begin = static_cast<uint32_t>(live.size());
    live.insert(live.end(), coarse_.begin() + span.begin, coarse_.begin() + span.begin + span.count);
    span.begin = span.count ? begin : 0;
  }
  coarse_ = std::move(live);
  coarse_garbage_ = 0;
}

void TemporalMap::rebuildCoarse(uint32_t node) {
  if (!coarse_dirty_[node]) return;
  coarse_dirty_[node] = 0;
  for (const Ref r : inner_[node]) {
    if (isInner(r)) rebuildCoarse(r);
  }
  coarse_garbage_ += coarse_span_[node].count;
  coarse_span_[node] = CoarseSpan{};
  if (node == 0) return;  // the root is never one leaf (compressFree never replaces it)
  // Each child's intervals of "reads free without hits", one run per child in `scratch`.
  std::vector<Coarse>& scratch = coarse_scratch_;
  scratch.clear();
  std::array<size_t, 9> run{};
  for (int slot = 0; slot < 8; ++slot) {
    const Ref r = inner_[node][slot];
    run[static_cast<size_t>(slot)] = scratch.size();
    if (r == kEmpty) return;
    if (isInner(r)) {
      const CoarseSpan span = coarse_span_[r];
      if (span.count == 0) return;
      scratch.insert(scratch.end(), coarse_.begin() + span.begin, coarse_.begin() + span.begin + span.count);
    } else {
      const List& l = lists_[index(r)];
      const Stored* e = entriesOf(l);
      const size_t before = scratch.size();
      for (size_t i = 0; i < l.size; ++i) {
        if (!freeWithoutHits(e[i])) continue;
        scratch.push_back(Coarse{e[i].session, i + 1 < l.size ? e[i + 1].session : kForever, e[i].length_m});
      }
      if (scratch.size() == before) return;
    }
  }
  run[8] = scratch.size();
  // Intersect the 8 runs: where all children read free, the cube does, with their lengths summed
  // in slot order (as compressFree() sums them).
  std::array<size_t, 8> at{};
  for (size_t i = 0; i < 8; ++i) at[i] = run[i];
  const auto begin = static_cast<uint32_t>(coarse_.size());
  while (true) {
    uint32_t lo = 0, hi = kForever;
    for (size_t i = 0; i < 8; ++i) {
      lo = std::max(lo, scratch[at[i]].from);
      hi = std::min(hi, scratch[at[i]].to);
    }
    if (lo < hi) {
      float sum = 0.0f;
      for (size_t i = 0; i < 8; ++i) sum += scratch[at[i]].length_m;
      if (coarse_.size() > begin && coarse_.back().to == lo && coarse_.back().length_m == sum) {
        coarse_.back().to = hi;
      } else {
        coarse_.push_back(Coarse{lo, hi, sum});
      }
    }
    if (hi == kForever) break;
    bool done = false;
    for (size_t i = 0; i < 8; ++i) {
      if (scratch[at[i]].to == hi && ++at[i] == run[i + 1]) done = true;
    }
    if (done) break;
  }
  coarse_span_[node] = CoarseSpan{begin, static_cast<uint32_t>(coarse_.size() - begin), Coarse{}};
  if (coarse_span_[node].count > 0) coarse_span_[node].newest = coarse_.back();
}

const TemporalMap::Coarse* TemporalMap::coarseBefore(const CoarseSpan& span, uint32_t rank) const {
  const Coarse* first = coarse_.data() + span.begin;
  const Coarse* last = first + span.count;
  const Coarse* it = std::upper_bound(first, last, rank, [](uint32_t r, const Coarse& c) { return r < c.from; });
  if (it == first) return nullptr;
  --it;
  return rank < it->to ? it : nullptr;
}

}  // namespace chronomap
