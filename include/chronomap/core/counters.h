#pragma once
/// @file
/// The counters a voxel accumulates (thesis §2.1) and the occupancy they imply.

#include <cmath>
#include <cstdint>

namespace chronomap {

/// Occupancy state of a voxel. Unknown is never the same as free.
enum class VoxelState : uint8_t { Unknown = 0, Free = 1, Occupied = 2 };

/// Name of a state ("unknown", "free", "occupied").
const char* toString(VoxelState state);

/// An 8-bit colour.
struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb&, const Rgb&) = default;
};

/// Counters of one voxel: summed ray length through it, rays ending in it, colour sums of those
/// end points. 20 bytes.
struct VoxelCounters {
  /// Summed length in metres of every ray segment inside the voxel (end segments included).
  float length_m = 0.0f;
  /// Number of rays that ended in the voxel.
  uint32_t hits = 0;
  /// Sums of the colour channels of the end points.
  uint32_t red = 0, green = 0, blue = 0;

  /// P = 1 - exp(-hits / length). A voxel with hits but zero length (a ray that ended exactly
  /// on the voxel's entry face) counts as certainly occupied; a voxel never traversed is 0.
  double probability() const {
    if (length_m > 0.0f) return 1.0 - std::exp(-static_cast<double>(hits) / static_cast<double>(length_m));
    return hits > 0 ? 1.0 : 0.0;
  }
  /// Unknown when never traversed; occupied when P > 0.5; free otherwise.
  VoxelState state() const {
    if (length_m <= 0.0f && hits == 0) return VoxelState::Unknown;
    return probability() > 0.5 ? VoxelState::Occupied : VoxelState::Free;
  }
  /// Mean colour of the end points (black when there are none).
  Rgb meanColor() const {
    if (hits == 0) return {};
    auto mean = [this](uint32_t sum) { return static_cast<uint8_t>((sum + hits / 2) / hits); };
    return {mean(red), mean(green), mean(blue)};
  }
  /// True for the voxels §2.1 may merge: traversed (length > 0) and never hit.
  bool isKnownFreeWithoutHits() const { return length_m > 0.0f && hits == 0; }

  VoxelCounters& operator+=(const VoxelCounters& o) {
    length_m += o.length_m;
    hits += o.hits;
    red += o.red;
    green += o.green;
    blue += o.blue;
    return *this;
  }
  friend bool operator==(const VoxelCounters&, const VoxelCounters&) = default;
};
static_assert(sizeof(VoxelCounters) == 20, "VoxelCounters must stay compact");
static_assert(sizeof(Rgb) == 3, "Rgb is read and written as three bytes");

}  // namespace chronomap
