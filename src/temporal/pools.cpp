// TemporalMap's pools: inner nodes, list records, blocks of the entry arena and hit parts, taken
// and given back, and entries inserted into and erased from a list. (Decoding a stored entry,
// valueOf() and decoded(), stays in temporal_map.cpp beside the queries that call it per entry.)
#include "chronomap/temporal/temporal_map.h"

#include <algorithm>

#include "chronomap/core/error.h"
#include "chronomap/core/offset_quantiser.h"
#include "pool_limits.h"

namespace chronomap {

using temporal_detail::kMaxIndex;
using temporal_detail::kMaxListSize;

uint32_t TemporalMap::newInner() {
  if (inner_.size() >= kMaxIndex) throw DataError("4D map too large: more than 2^31 inner nodes");
  inner_.emplace_back();
  inner_.back().fill(kEmpty);
  coarse_span_.emplace_back();
  coarse_dirty_.push_back(1);
  return static_cast<uint32_t>(inner_.size() - 1);
}

TemporalMap::Stored TemporalMap::store(uint32_t session, const VoxelCounters& value) {
  Stored s{session, value.length_m, kNoPart};
  if (!keepsHitPart(value)) return s;
  HitPart p{value.hits, value.red, value.green, value.blue, {}, 0};
  for (int a = 0; a < 3; ++a) p.offset[a] = quantiseOffset(value.offset[a], value.hits);
  if (!free_hit_parts_.empty()) {
    s.part = free_hit_parts_.back();
    free_hit_parts_.pop_back();
    hit_parts_[s.part] = p;
  } else {
    if (hit_parts_.size() >= kMaxIndex) throw DataError("4D map too large: more than 2^31 entries with hits");
    s.part = static_cast<uint32_t>(hit_parts_.size());
    hit_parts_.push_back(p);
  }
  return s;
}

void TemporalMap::release(const Stored& s) {
  if (s.part != kNoPart) free_hit_parts_.push_back(s.part);
}

uint32_t TemporalMap::newList(const Stored& e) {
  ++live_lists_;
  ++live_entries_;
  if (!free_lists_.empty()) {
    const uint32_t i = free_lists_.back();
    free_lists_.pop_back();
    lists_[i] = List{e, 0, 1, 0, 0};
    return i;
  }
  if (lists_.size() >= kMaxIndex) throw DataError("4D map too large: more than 2^31 slot lists");
  lists_.push_back(List{e, 0, 1, 0, 0});
  return static_cast<uint32_t>(lists_.size() - 1);
}

void TemporalMap::freeList(uint32_t list) {
  List& l = lists_[list];
  const Stored* e = entriesOf(l);
  for (size_t i = 0; i < l.size; ++i) release(e[i]);
  if (l.size >= 2) freeBlock(l.block, l.capacity_log2);
  live_entries_ -= l.size;
  --live_lists_;
  l = List{};
  free_lists_.push_back(list);
}

uint32_t TemporalMap::allocBlock(int capacity_log2) {
  auto& free = free_blocks_[static_cast<size_t>(capacity_log2)];
  if (!free.empty()) {
    const uint32_t b = free.back();
    free.pop_back();
    return b;
  }
  const size_t at = arena_.size();
  if (at + (size_t{1} << capacity_log2) >= kMaxIndex) throw DataError("4D map too large: more than 2^31 entries");
  arena_.resize(at + (size_t{1} << capacity_log2));
  return static_cast<uint32_t>(at);
}

void TemporalMap::freeBlock(uint32_t block, int capacity_log2) {
  free_blocks_[static_cast<size_t>(capacity_log2)].push_back(block);
}

void TemporalMap::insertEntry(uint32_t list, size_t pos, const Stored& e) {
  List& l = lists_[list];
  if (l.size >= kMaxListSize) throw DataError("4D map: a voxel has more than 65535 history entries");
  if (l.size == 0) {  // emptied by eraseEntry, refilled before it is freed
    l.first = e;
    l.size = 1;
    ++live_entries_;
    return;
  }
  if (l.size == 1) {
    const Stored only = l.first;
    const uint32_t block = allocBlock(1);
    List& m = lists_[list];  // allocBlock does not touch lists_, but keep the reference fresh
    m.block = block;
    m.capacity_log2 = 1;
    arena_[block + (pos == 0 ? 1 : 0)] = only;
    arena_[block + pos] = e;
    m.size = 2;
    m.first = arena_[block + 1];
    ++live_entries_;
    return;
  }
  if (l.size == (size_t{1} << l.capacity_log2)) {
    const int cap = l.capacity_log2 + 1;
    const uint32_t block = allocBlock(cap);
    std::copy(arena_.begin() + l.block, arena_.begin() + l.block + l.size, arena_.begin() + block);
    freeBlock(l.block, l.capacity_log2);
    l.block = block;
    l.capacity_log2 = static_cast<uint8_t>(cap);
  }
  Stored* data = arena_.data() + l.block;
  std::copy_backward(data + pos, data + l.size, data + l.size + 1);
  data[pos] = e;
  ++l.size;
  l.first = data[l.size - 1];
  ++live_entries_;
}

void TemporalMap::eraseEntry(uint32_t list, size_t pos) {
  List& l = lists_[list];
  release(entriesOf(l)[pos]);
  if (l.size == 1) {
    l.size = 0;
    --live_entries_;
    return;
  }
  Stored* data = arena_.data() + l.block;
  std::copy(data + pos + 1, data + l.size, data + pos);
  --l.size;
  --live_entries_;
  if (l.size == 1) {
    const Stored only = data[0];
    freeBlock(l.block, l.capacity_log2);
    l.first = only;
    l.block = 0;
    l.capacity_log2 = 0;
  } else {
    l.first = data[l.size - 1];
  }
}

}  // namespace chronomap
