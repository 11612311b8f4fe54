#pragma once
/// @file
/// Raster images: what depth cameras deliver and what the renderers draw.

#include <cstdint>
#include <vector>

#include "chronomap/core/counters.h"

namespace chronomap {

/// An 8-bit RGB image, row-major.
struct ImageRgb {
  uint32_t width = 0, height = 0;
  std::vector<Rgb> pixels;
};

/// A 16-bit single-channel image (depth), row-major.
struct ImageU16 {
  uint32_t width = 0, height = 0;
  std::vector<uint16_t> pixels;
};

}  // namespace chronomap
