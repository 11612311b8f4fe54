#pragma once
/// @file
/// Integration of frames one at a time, as they arrive (a SLAM loop, a Python notebook), into
/// a map the integrator holds.

#include <cstddef>

#include "chronomap/core/frame.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Integrates frames one by one. finish() gives bitwise the map integrate() makes of the same
/// frames in the same order with the same settings: frames are merged as integrate() merges
/// them, and known-free space is compressed once, at the end (when settings.compress_free).
class IncrementalIntegrator {
 public:
  /// @throw UsageError for a bad resolution or bad settings.
  explicit IncrementalIntegrator(double resolution_m, const IntegratorSettings& settings = {});
  IncrementalIntegrator(const IncrementalIntegrator&) = delete;
  IncrementalIntegrator& operator=(const IncrementalIntegrator&) = delete;

  /// Casts the rays of `frame` on this thread and merges them into the map.
  /// @throw DataError for a pose that is not finite or lies outside the map; UsageError past
  /// settings.memory_limit_bytes.
  IntegrationStats add(const Frame& frame);

  /// The map so far (not yet compressed).
  const SessionMap& map() const { return map_; }
  /// Everything added so far.
  const IntegrationStats& stats() const { return stats_; }
  const IntegratorSettings& settings() const { return settings_; }

  /// The map, compressed as integrate() leaves it; the integrator starts again empty.
  SessionMap finish();

 private:
  IntegratorSettings settings_;
  SessionMap map_;
  RayAccumulator accumulator_;
  VoxelDeltas deltas_;
  IntegrationStats stats_;
};

}  // namespace chronomap
