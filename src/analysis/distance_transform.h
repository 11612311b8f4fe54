#pragma once
/// @file
/// Internal to the analysis module: the exact Euclidean distance transform that inflate()
/// (analysis/costmap.h) measures the robot's radius with.

#include <cstdint>
#include <functional>
#include <vector>

namespace chronomap::analysis_detail {

/// What forEachSquaredDistance reports for a cell when the grid holds no source cell at all.
inline constexpr int64_t kNoSource = INT64_MAX;

/// For every cell of a `width` x `height` grid (row-major, row 0 first), the squared Euclidean
/// distance in cells from its centre to the nearest centre of a cell whose `source` byte is
/// non-zero: 0 on a source, kNoSource where there is none. Exact (integer arithmetic, the
/// separable lower-envelope method of Meijster, Roerdink and Hesselink, 2000), in time linear in
/// the grid and memory of 4 bytes a cell, whatever the distances. `row(j, d2)` receives row j's
/// `width` distances, rows in order.
void forEachSquaredDistance(const std::vector<uint8_t>& source, int width, int height,
                            const std::function<void(int, const int64_t*)>& row);

}  // namespace chronomap::analysis_detail
