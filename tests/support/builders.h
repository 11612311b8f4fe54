#pragma once
// Builders of test inputs shared by the test programs: voxel keys and counters, session maps
// (random, a wall), clouds.

#include <cstdint>
#include <initializer_list>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/counters.h"
#include "chronomap/core/image.h"
#include "chronomap/core/key.h"
#include "chronomap/core/point_cloud.h"
#include "chronomap/octree/session_map.h"

namespace chronomap::test {

/// A Monday the time tests count from: 2012-03-05 00:00 UTC.
inline constexpr double kMonday_s = 1330905600.0;
inline constexpr double kHour = 3600.0;  ///< seconds

/// The pixel at column x, row y.
inline Rgb pixel(const ImageRgb& img, int x, int y) {
  return img.pixels[static_cast<size_t>(y) * img.width + static_cast<size_t>(x)];
}

/// The key of the voxel (x, y, z) voxels from `origin` on every axis (default the map origin,
/// kKeyOrigin; a test region that straddles the root's centre starts a few voxels below it).
VoxelKey at(int x, int y, int z, int origin = kKeyOrigin);

/// True when two session maps are equal node for node: the same pools when laid out depth first
/// (SessionMap::pools(): the same tree, leaf by leaf).
bool samePools(const SessionMap& a, const SessionMap& b);

/// A voxel crossed by rays of `length` metres in all, none ending in it.
VoxelCounters freeVoxel(float length = 0.05f);

/// A voxel where `hits` rays of the given colour ended, 0.025 m of ray per hit.
VoxelCounters occupiedVoxel(Rgb colour, uint32_t hits = 10);

/// A voxel where `hits` rays ended, 1/16 m of ray per hit (a binary fraction, so that sums of
/// such counters stay exact in float), colour (red, 10, 20).
VoxelCounters occupiedVoxelExact(uint32_t hits, uint8_t red = 200);

/// Counters equal but for rounding in the summed length.
bool nearlyEqual(const VoxelCounters& a, const VoxelCounters& b);

/// A 16 x 16 wall in the plane x = wall_x, seen from -x: free voxels x = first_free_x .. wall_x - 1
/// (freeVoxel()), the wall occupied (occupiedVoxel()) with a colour per (y, z), (16 y, 16 z, 128);
/// nothing behind it. 0.05 m voxels.
SessionMap wallSession(int wall_x, int first_free_x = 4);

/// A random session map over a side^3 block of voxels at the map origin: each voxel observed
/// with probability 0.9, occupied with probability `occupied`, free subtrees compressed.
SessionMap randomSessionMap(uint64_t seed, int side = 16, double occupied = 0.1, double resolution_m = 0.05);

/// The tile tests' region: voxels [kTileRegionLo, kTileRegionHi) per axis around the map origin,
/// so that tiles of every level cut through it (the origin is a corner of every tile level).
inline constexpr int kTileRegionLo = -6, kTileRegionHi = 10;

/// A random session over a random box of the tile tests' region: `world` (one byte a voxel of the
/// region, 0 free, kept between calls) drifts by 40 flips, then occupied voxels, holes and free
/// space with binary-fraction lengths (sums stay exact), sometimes compressed; now and then a
/// known-free cube of 16 voxels at x = 16, so that uniform cubes of tile size and larger occur.
/// `far_parts` adds, now and then, a cube of 32 voxels at x = 32 and an occupied voxel at x = 40..47
/// (a later session refines a cube of the top below tile level).
SessionMap randomTileRegionSession(std::mt19937_64& rng, std::vector<uint8_t>& world, bool far_parts);

/// The changes scene (docs/changes.md's analytic case), 0.05 m voxels: the block x 0..35,
/// y 0..15, z 0..9 observed, free but for its objects; a grey wall at x = 34 in both states.
/// Earlier: a red 4 x 4 x 4 box A at (2..5, 2..5, 1..4) and a green 3 x 3 x 3 box C at
/// (2..4, 10..12, 1..3). Later: A gone; a blue 3 x 3 x 8 box B at (12..14, 2..4, 1..8); C moved
/// by 18 voxels (0.9 m) in x to (20..22, 10..12, 1..3); a 2 x 2 x 2 box D at (12..13, 12..13,
/// 1..2), too small for an object; and a 5 x 5 patch P one voxel thick at x = 31, y 5..9, z 3..7,
/// three voxels before the wall, which the weak-change rule takes for the wall measured nearer.
SessionMap changesScene(bool later);

/// A cloud of the given points (no colour).
PointCloud cloudOf(std::initializer_list<Eigen::Vector3f> points);

/// A camera at `position` in its optical frame (x right, y down, z forward) looking along
/// `yaw` (radians, 0: +x) and `pitch` (radians, up positive), its x axis level.
Eigen::Isometry3d cameraLooking(const Eigen::Vector3d& position, double yaw, double pitch = 0.0);

}  // namespace chronomap::test
