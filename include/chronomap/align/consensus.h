#pragma once
/// @file
/// The consensus map (thesis §2.2): what many recordings of one place agree on.

#include <span>

#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// The consensus of session maps: for every volume the sums of all maps' counters (ray
/// length, hits, colour sums). A compressed free node of one map is spread evenly over the
/// unit voxels where another map is finer, so a voxel's consensus counters are the sums of
/// what every map's find() reports for it. Linear in the nodes of the maps.
/// @throw UsageError for no maps, a null map or maps of different resolutions.
SessionMap consensus(std::span<const SessionMap* const> maps);
/// The same for maps held by value.
SessionMap consensus(std::span<const SessionMap> maps);

/// The consensus of a 4D map over the sessions with a time in [t0_s, t1_s]: the sum of its
/// snapshots at those sessions' times (every voxel counts the state valid at each of them,
/// that is, each history entry weighted by the number of those sessions it was valid for).
/// Without the session maps themselves, this is the nearest the 4D map comes to their
/// consensus: a session that did not observe a voxel contributes the state seen before it.
/// Empty when no session lies in the range. Linear in the map's lists.
/// @throw UsageError when t0_s > t1_s or either is NaN.
SessionMap consensus(const TemporalMap& map, double t0_s, double t1_s);

}  // namespace chronomap
