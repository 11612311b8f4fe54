#include "chronomap/temporal/coverage.h"

#include <algorithm>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

constexpr uint64_t kMortonEnd = uint64_t{1} << (3 * kTreeDepth);

void putVarint(std::vector<uint8_t>& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<uint8_t>(v | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<uint8_t>(v));
}

uint64_t getVarint(const std::vector<uint8_t>& in, size_t& pos) {
  uint64_t v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (pos >= in.size()) throw FormatError("coverage ends inside a number");
    const uint8_t b = in[pos++];
    v |= static_cast<uint64_t>(b & 0x7f) << shift;
    if ((b & 0x80) == 0) return v;
  }
  throw FormatError("coverage holds an over-long number");
}

}  // namespace

Coverage::Coverage(const SessionMap& map) {
  std::vector<uint64_t> ranges;
  map.forEachLeaf([&](const LeafView& leaf) {
    const uint64_t begin = mortonEncode(leaf.key);
    const uint64_t end = begin + (uint64_t{1} << (3 * leaf.level));
    if (!ranges.empty() && ranges.back() == begin) {
      ranges.back() = end;  // leaves come in Morton order: extend the current run
    } else {
      ranges.push_back(begin);
      ranges.push_back(end);
    }
  });
  *this = fromRanges(ranges);
}

Coverage Coverage::fromRanges(const std::vector<uint64_t>& pairs) {
  if (pairs.size() % 2 != 0) throw FormatError("coverage has an odd number of range bounds");
  Coverage c;
  putVarint(c.encoded_, pairs.size() / 2);
  uint64_t previous_end = 0;
  for (size_t i = 0; i < pairs.size(); i += 2) {
    const uint64_t b = pairs[i], e = pairs[i + 1];
    if (b >= e || e > kMortonEnd || (i > 0 && b <= previous_end)) {
      throw FormatError("coverage ranges are not sorted, disjoint and inside the map");
    }
    putVarint(c.encoded_, b - previous_end);
    putVarint(c.encoded_, e - b);
    c.voxels_ += e - b;
    previous_end = e;
  }
  c.encoded_.shrink_to_fit();
  return c;
}

Coverage Coverage::decodeFrom(const std::vector<uint8_t>& bytes, size_t& pos) {
  // One pass that checks what fromRanges checks and that every number is in its shortest form
  // (so that the bytes are the canonical encoding), then keeps the bytes as they are.
  const size_t start = pos;
  const uint8_t* p = bytes.data() + pos;
  const uint8_t* const end = bytes.data() + bytes.size();
  auto number = [&]() {
    uint64_t v = 0;
    for (int shift = 0;; shift += 7) {
      if (p == end) throw FormatError("coverage ends inside a number");
      if (shift >= 64) throw FormatError("coverage holds an over-long number");
      const uint8_t b = *p++;
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) {
        if (b == 0 && shift > 0) throw FormatError("coverage is not in its canonical encoding");
        return v;
      }
    }
  };
  const uint64_t n = number();
  // Each range takes at least two bytes (two varints): refuse a count the bytes left cannot hold.
  if (n > static_cast<uint64_t>(end - p) / 2) throw FormatError("coverage claims more ranges than it holds");
  Coverage c;
  uint64_t previous_end = 0;
  for (uint64_t i = 0; i < n; ++i) {
    const uint64_t gap = number(), length = number();
    if (gap > kMortonEnd || length > kMortonEnd) throw FormatError("coverage range outside the map");
    const uint64_t b = previous_end + gap, e = b + length;
    if (length == 0 || e > kMortonEnd || (i > 0 && gap == 0)) {
      throw FormatError("coverage ranges are not sorted, disjoint and inside the map");
    }
    c.voxels_ += length;
    previous_end = e;
  }
  pos = static_cast<size_t>(p - bytes.data());
  c.encoded_.assign(bytes.begin() + static_cast<std::ptrdiff_t>(start),
                    bytes.begin() + static_cast<std::ptrdiff_t>(pos));
  return c;
}

std::vector<uint64_t> Coverage::ranges() const {
  size_t pos = 0;
  std::vector<uint64_t> out;
  if (encoded_.empty()) return out;
  const uint64_t n = getVarint(encoded_, pos);
  out.reserve(2 * n);
  uint64_t previous_end = 0;
  for (uint64_t i = 0; i < n; ++i) {
    const uint64_t gap = getVarint(encoded_, pos), length = getVarint(encoded_, pos);
    out.push_back(previous_end + gap);
    out.push_back(previous_end + gap + length);
    previous_end = out.back();
  }
  return out;
}

CoverageIndex::Overlap CoverageIndex::overlap(const VoxelKey& corner, int level) const {
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

}  // namespace chronomap
