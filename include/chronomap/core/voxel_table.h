#pragma once
/// @file
/// A hash table from a voxel's Morton code to a value, for the many lookups of the registration
/// (align/register.cpp): open addressing with linear probing in one flat array of codes and one
/// of values, so that a lookup, found or not, mostly touches one cache line, and clear() keeps
/// the memory for the next use. Same contents as a std::unordered_map<uint64_t, V> given the
/// same insertions (tested against it); only the order of forEach() differs.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace chronomap {

template <typename V>
class VoxelTable {
 public:
  /// Never a Morton code: mortonEncode() uses 48 bits.
  static constexpr uint64_t kEmpty = ~uint64_t{0};

  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

  /// The value of `code`, or nullptr.
  const V* find(uint64_t code) const {
    if (codes_.empty()) return nullptr;
    for (size_t i = slotOf(code);; i = (i + 1) & mask_) {
      if (codes_[i] == code) return &values_[i];
      if (codes_[i] == kEmpty) return nullptr;
    }
  }
  V* find(uint64_t code) { return const_cast<V*>(std::as_const(*this).find(code)); }
  bool contains(uint64_t code) const { return find(code) != nullptr; }
  /// Asks the processor to fetch the slot where find(code) starts (a hint; nothing changes):
  /// lookups in a table larger than the cache can then overlap instead of waiting in turn.
  void prefetch(uint64_t code) const {
    if (codes_.empty()) return;
    const size_t i = slotOf(code);
    __builtin_prefetch(&codes_[i]);
    __builtin_prefetch(&values_[i]);
  }

  /// The value of `code`, inserted as `init` when missing. The reference stays valid until the
  /// next insertion.
  V& tryEmplace(uint64_t code, const V& init) {
    if (2 * (size_ + 1) > codes_.size()) grow();
    size_t i = slotOf(code);
    for (; codes_[i] != kEmpty; i = (i + 1) & mask_) {
      if (codes_[i] == code) return values_[i];
    }
    codes_[i] = code;
    values_[i] = init;
    ++size_;
    return values_[i];
  }

  /// Removes every entry; the memory is kept.
  void clear() {
    if (size_ == 0) return;
    std::fill(codes_.begin(), codes_.end(), kEmpty);
    size_ = 0;
  }

  /// Calls fn(code, value) for every entry, in no particular order.
  template <typename Fn>
  void forEach(Fn&& fn) const {
    for (size_t i = 0; i < codes_.size(); ++i) {
      if (codes_[i] != kEmpty) fn(codes_[i], values_[i]);
    }
  }

 private:
  size_t slotOf(uint64_t code) const {
    // Fibonacci hashing: neighbouring codes spread over the table.
    return static_cast<size_t>((code * 0x9E3779B97F4A7C15ULL) >> shift_);
  }

  void grow() {
    const size_t capacity = codes_.empty() ? 64 : 2 * codes_.size();
    std::vector<uint64_t> old_codes(capacity, kEmpty);
    std::vector<V> old_values(capacity);
    old_codes.swap(codes_);
    old_values.swap(values_);
    mask_ = capacity - 1;
    shift_ = 64;
    for (size_t c = capacity; c > 1; c >>= 1) --shift_;
    for (size_t j = 0; j < old_codes.size(); ++j) {
      if (old_codes[j] == kEmpty) continue;
      size_t i = slotOf(old_codes[j]);
      while (codes_[i] != kEmpty) i = (i + 1) & mask_;
      codes_[i] = old_codes[j];
      values_[i] = std::move(old_values[j]);
    }
  }

  std::vector<uint64_t> codes_;
  std::vector<V> values_;
  size_t size_ = 0;
  size_t mask_ = 0;
  int shift_ = 64;
};

}  // namespace chronomap
