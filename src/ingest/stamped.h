#pragma once
// Association by time shared by the readers (internal): the element of a time-sorted list
// nearest to a stamp, within a tolerance.

#include <algorithm>
#include <cmath>
#include <iterator>
#include <vector>

namespace chronomap {

/// The element of `sorted` (increasing member `t`) nearest to `t` and at most `tolerance`
/// away, or null; of two equally near, the earlier.
template <class T>
const T* nearestInTime(const std::vector<T>& sorted, double t, double tolerance) {
  auto it = std::lower_bound(sorted.begin(), sorted.end(), t, [](const T& a, double v) { return a.t < v; });
  const T* best = nullptr;
  double best_dt = tolerance;
  if (it != sorted.end() && std::abs(it->t - t) <= best_dt) {
    best = &*it;
    best_dt = std::abs(it->t - t);
  }
  if (it != sorted.begin() && std::abs(std::prev(it)->t - t) <= best_dt) best = &*std::prev(it);
  return best;
}

}  // namespace chronomap
