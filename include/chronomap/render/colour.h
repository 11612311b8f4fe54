#pragma once
/// @file
/// Colour ramps that turn numbers into colours, for pictures and coloured point clouds.

#include "chronomap/core/counters.h"
#include "chronomap/core/image.h"

namespace chronomap {

/// Blue (t = 0) through green to red (t = 1); t is clamped to [0, 1].
Rgb heatColour(double t);

/// A depth image in false colour: blue near, red far over 0..5 m; zero depth (no measurement)
/// black. `depth_scale` is the image's units per metre.
ImageRgb colourizeDepth(const ImageU16& depth, double depth_scale);

}  // namespace chronomap
