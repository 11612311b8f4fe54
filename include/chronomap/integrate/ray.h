#pragma once
/// @file
/// Exact voxel traversal of a ray segment (Amanatides & Woo 3D DDA) with the length of the
/// segment inside every voxel.

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>

namespace chronomap {

/// Visits every unit voxel that the segment from `origin` to `end` passes through, in order,
/// calling visit(x, y, z, length, is_last) with integer voxel coordinates and the length of the
/// segment inside that voxel. Coordinates are in key space (units of voxels). The last voxel is
/// always the one containing `end` (floor of its coordinates); the lengths sum to |end - origin|
/// exactly up to rounding, because each is a difference of consecutive crossing parameters.
/// The number of voxels visited is 1 + the L1 distance between the first and last voxel.
template <class Visit>
inline void traverseRay(const double origin[3], const double end[3], Visit&& visit) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  int64_t cur[3], last[3], step[3];
  double t_max[3], t_delta[3], d[3];
  int64_t remaining = 0;
  for (int a = 0; a < 3; ++a) {
    cur[a] = static_cast<int64_t>(std::floor(origin[a]));
    last[a] = static_cast<int64_t>(std::floor(end[a]));
    d[a] = end[a] - origin[a];
    remaining += std::llabs(last[a] - cur[a]);
  }
  const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  for (int a = 0; a < 3; ++a) {
    if (cur[a] == last[a]) {
      step[a] = 0;
      t_max[a] = kInf;
      t_delta[a] = kInf;
    } else if (d[a] > 0) {
      step[a] = 1;
      t_delta[a] = 1.0 / d[a];
      t_max[a] = (static_cast<double>(cur[a]) + 1.0 - origin[a]) * t_delta[a];
    } else {
      step[a] = -1;
      t_delta[a] = -1.0 / d[a];
      t_max[a] = (origin[a] - static_cast<double>(cur[a])) * t_delta[a];
    }
  }
  double t = 0.0;
  for (; remaining > 0; --remaining) {
    // On ties x goes first, then y (the integrator's specialised copy does the same).
    const int a = (t_max[0] <= t_max[1] && t_max[0] <= t_max[2]) ? 0 : (t_max[1] <= t_max[2] ? 1 : 2);
    double t_next = t_max[a];
    if (t_next < t) t_next = t;  // rounding can order crossings a hair early; keep t monotonic
    if (t_next > 1.0) t_next = 1.0;
    visit(cur[0], cur[1], cur[2], (t_next - t) * length, false);
    t = t_next;
    cur[a] += step[a];
    t_max[a] = cur[a] == last[a] ? kInf : t_max[a] + t_delta[a];
  }
  visit(cur[0], cur[1], cur[2], (1.0 - t) * length, true);
}

}  // namespace chronomap
