#pragma once
// Internals of the simulator shared by its files: portable randomness, where the building and
// the camera sit, the patrol's poses and the truth of a change event.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/sim/building.h"

namespace chronomap::sim_detail {

// Randomness that is the same on every platform (std distributions are not).
struct Rng {
  uint64_t state;
  explicit Rng(uint64_t seed) : state(seed * 0x9e3779b97f4a7c15ULL + 0x632be59bd9b4e019ULL) {}
  uint64_t next() {  // SplitMix64
    uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  bool chance(double p) { return uniform() < p; }
  int below(int n) { return static_cast<int>(next() % static_cast<uint64_t>(n)); }
  double normal() {  // Box-Muller
    const double u1 = uniform(), u2 = uniform();
    return normalOf(u1, u2);
  }
  // The normal() drawn from its two uniforms, for callers that draw them and may not need it.
  static double normalOf(double u1, double u2) {
    return std::sqrt(-2.0 * std::log(std::max(u1, 1e-300))) * std::cos(2.0 * std::numbers::pi * u2);
  }
};

inline uint64_t mix(uint64_t a, uint64_t b) { return Rng(a ^ (b * 0xd1342543de82ef95ULL)).next(); }

inline constexpr double kCameraHeight = 1.2;
inline constexpr double kCameraPitchDeg = -12.0;
// Shift of the whole building against the voxel grid, so that floors and walls do not lie on
// voxel faces (a real map frame has no reason to align with them).
inline const Eigen::Vector3d kOffset(0.013, 0.021, 0.017);

// Centre of an object's parts in x, y (scene.cpp).
Eigen::Vector2d centerOf(const Object& o);
// Moves every part of `o` by `d`.
inline void translate(Object& o, const Eigen::Vector3d& d) {
  for (Part& p : o.parts) p.box.translate(d);
}

// One session's patrol (patrol.cpp): the true camera poses, the estimated ones (the true ones
// with the session's localisation offset and a drift), one per frame, and the offset.
struct Patrol {
  std::vector<Eigen::Isometry3d> true_poses, estimated;
  double offset_x_m = 0.0, offset_y_m = 0.0, offset_yaw_rad = 0.0;
};
Patrol patrolSession(const SceneState& state, const SimulationSettings& settings, int session);

// The change `kind` to object `id` between the states of two consecutive sessions, with the truth
// voxels (truthOccupancy() of each state) it changes (truth.cpp); from_session is left 0. No
// voxels: hidden by other objects.
ChangeEvent changeEvent(uint32_t id, EventKind kind, const SceneState& previous_state, const SceneState& state,
                        const std::vector<VoxelKey>& previous_truth, const std::vector<VoxelKey>& truth,
                        const KeyGrid& grid);
// The truth voxels as a session map, each occupied with one hit (truth.cpp).
SessionMap truthMap(const std::vector<VoxelKey>& truth, const KeyGrid& grid);

}  // namespace chronomap::sim_detail
