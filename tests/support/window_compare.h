#pragma once
// Comparing a history kept as windows (temporal/window.h) with the one map: the window tests'
// and the windowed tiles' (tests/pipeline/stream_test.cpp).

#include <gtest/gtest.h>

#include <tuple>
#include <vector>

#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap::test {

/// Same sessions (times, names, coverage; node counts are each window's own) and the same
/// tree, lists and entries, bit for bit.
inline ::testing::AssertionResult sameHistory(const TemporalMap& joined, const TemporalMap& whole) {
  if (joined.sessionCount() != whole.sessionCount()) return ::testing::AssertionFailure() << "session counts differ";
  for (size_t i = 0; i < whole.sessionCount(); ++i) {
    const SessionRecord &a = joined.sessions()[i], &b = whole.sessions()[i];
    if (a.time_s != b.time_s || a.name != b.name || !(a.coverage == b.coverage)) {
      return ::testing::AssertionFailure() << "session " << i << " differs";
    }
  }
  const TemporalMap::Parts a = joined.parts(), b = whole.parts();
  if (a.inner != b.inner) return ::testing::AssertionFailure() << "trees differ";
  if (a.list_sizes != b.list_sizes) return ::testing::AssertionFailure() << "list sizes differ";
  if (a.entries != b.entries) return ::testing::AssertionFailure() << "entries differ";
  return ::testing::AssertionSuccess();
}

/// The same leaves with the same counters, but that free leaves without hits may differ in length.
inline ::testing::AssertionResult sameButFreeLengths(const SessionMap& a, const SessionMap& b) {
  std::vector<std::tuple<VoxelKey, int, VoxelCounters>> la, lb;
  a.forEachLeaf([&](const LeafView& l) { la.emplace_back(l.key, l.level, l.counters); });
  b.forEachLeaf([&](const LeafView& l) { lb.emplace_back(l.key, l.level, l.counters); });
  if (la.size() != lb.size()) return ::testing::AssertionFailure() << la.size() << " leaves against " << lb.size();
  for (size_t i = 0; i < la.size(); ++i) {
    auto [ka, va, ca] = la[i];
    auto [kb, vb, cb] = lb[i];
    if (!(ka == kb) || va != vb) return ::testing::AssertionFailure() << "leaf " << i << " lies elsewhere";
    if (ca.hits == 0 && cb.hits == 0 && ca.length_m > 0.0f && cb.length_m > 0.0f) ca.length_m = cb.length_m;
    if (!(ca == cb)) return ::testing::AssertionFailure() << "leaf " << i << " differs";
  }
  return ::testing::AssertionSuccess();
}

}  // namespace chronomap::test
