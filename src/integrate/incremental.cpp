// IncrementalIntegrator: integrate() one frame at a time.
#include "chronomap/integrate/incremental.h"

#include <chrono>
#include <utility>

#include "ray_accumulator.h"

namespace chronomap {

using integrate_detail::checkMapMemory;
using integrate_detail::checkSettings;
using integrate_detail::perThread;

IncrementalIntegrator::IncrementalIntegrator(double resolution_m, const IntegratorSettings& settings)
    : settings_((checkSettings(settings), settings)),
      map_(resolution_m),
      accumulator_(map_.grid(), perThread(settings, 1)) {}

IntegrationStats IncrementalIntegrator::add(const Frame& frame) {
  const auto start = std::chrono::steady_clock::now();
  accumulator_.accumulate(frame, deltas_);
  mergeDeltas(map_, deltas_);
  checkMapMemory(map_, settings_);
  IntegrationStats frame_stats = deltas_.stats;
  frame_stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats_ += frame_stats;
  return frame_stats;
}

SessionMap IncrementalIntegrator::finish() {
  if (settings_.compress_free) map_.compressFree();
  SessionMap out = std::move(map_);
  map_ = SessionMap(out.resolution_m());
  stats_ = {};
  return out;
}

}  // namespace chronomap
