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
/// end points and the sums of where they ended. 32 bytes.
struct VoxelCounters {
  /// Summed length in metres of every ray segment inside the voxel (end segments included).
  float length_m = 0.0f;
  /// Number of rays that ended in the voxel.
  uint32_t hits = 0;
  /// Sums of the colour channels of the end points.
  uint32_t red = 0, green = 0, blue = 0;
  /// Sums of the end points' offsets from the voxel centre, x, y, z, in voxels (each within
  /// +-0.5): with `hits`, where in the voxel the surface lies, to a fraction of a voxel. Zero in
  /// maps made before chronomap kept them (the surface is then taken to be at the centre).
  float offset[3] = {0.0f, 0.0f, 0.0f};

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
  Rgb meanColour() const {
    if (hits == 0) return {};
    auto mean = [this](uint32_t sum) { return static_cast<uint8_t>((sum + hits / 2) / hits); };
    return {mean(red), mean(green), mean(blue)};
  }
  /// Mean offset of the end points from the voxel centre along `axis` (0..2), in voxels; 0
  /// without hits.
  double meanOffset(int axis) const { return hits > 0 ? static_cast<double>(offset[axis]) / hits : 0.0; }
  /// True when the offset sums are finite and possible: each within half a voxel per hit (and
  /// zero without hits). Readers refuse files where they are not.
  bool offsetsValid() const {
    const float limit = 0.5f * static_cast<float>(hits) * 1.001f;
    for (float o : offset) {
      if (!std::isfinite(o) || std::abs(o) > limit) return false;
    }
    return true;
  }
  /// True for the voxels §2.1 may merge: traversed (length > 0) and never hit.
  bool isKnownFreeWithoutHits() const { return length_m > 0.0f && hits == 0; }

  VoxelCounters& operator+=(const VoxelCounters& o) {
    length_m += o.length_m;
    hits += o.hits;
    red += o.red;
    green += o.green;
    blue += o.blue;
    for (int a = 0; a < 3; ++a) offset[a] += o.offset[a];
    return *this;
  }
  friend bool operator==(const VoxelCounters&, const VoxelCounters&) = default;
};
static_assert(sizeof(VoxelCounters) == 32, "VoxelCounters must stay compact");
static_assert(sizeof(Rgb) == 3, "Rgb is read and written as three bytes");

}  // namespace chronomap
