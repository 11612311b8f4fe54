#pragma once
/// @file
/// The one quantiser of hit positions: a voxel's mean hit offset along one axis as one byte, as
/// format version 2 files store it and as the 4D map keeps it in memory (so a map built in memory
/// answers exactly as the same map read back from its file).

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace chronomap {

/// Mean offsets (in voxels, -0.5..0.5) are kept as q = round(mean * 254) in -127..127, stored
/// as the byte q + 127 (0..254). Zero, a hit at the centre, is kept exactly.
inline constexpr int kOffsetLevels = 127;

/// std::round(x) (halves away from zero) for |x| <= 2^31, without a library call: the fraction
/// x - trunc(x) is exact there.
inline double roundHalfAway(double x) {
  const auto t = static_cast<double>(static_cast<int64_t>(x));
  return std::abs(x - t) >= 0.5 ? t + std::copysign(1.0, x) : t;
}

/// The byte of an offset sum `sum` over `hits` hits (127 without hits).
inline uint8_t quantiseOffset(float sum, uint32_t hits) {
  if (hits == 0) return kOffsetLevels;
  const double mean = static_cast<double>(sum) / static_cast<double>(hits);
  // Clamped a level beyond the range first (rounding is monotonic, so the byte is the same).
  const double x = std::clamp(mean * (2 * kOffsetLevels), -double{kOffsetLevels + 1}, double{kOffsetLevels + 1});
  const double q = roundHalfAway(x);
  return static_cast<uint8_t>(std::clamp(q, -double{kOffsetLevels}, double{kOffsetLevels}) + kOffsetLevels);
}

/// The offset sum that the byte `q` stands for over `hits` hits.
inline float dequantiseOffset(uint8_t q, uint32_t hits) {
  return static_cast<float>((static_cast<double>(q) - kOffsetLevels) / (2 * kOffsetLevels) * static_cast<double>(hits));
}

}  // namespace chronomap
