#include "chronomap/render/colour.h"

#include <algorithm>
#include <cmath>

namespace chronomap {

namespace {

uint8_t channel(double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }

}  // namespace

Rgb heatColour(double t) { return {channel(1.5 * t), channel(1.0 - 2.0 * std::abs(t - 0.5)), channel(1.5 * (1.0 - t))}; }

ImageRgb colourizeDepth(const ImageU16& depth, double depth_scale) {
  ImageRgb img;
  img.width = depth.width;
  img.height = depth.height;
  img.pixels.resize(depth.pixels.size());
  for (size_t i = 0; i < depth.pixels.size(); ++i) {
    if (depth.pixels[i] == 0) {
      img.pixels[i] = Rgb{0, 0, 0};
      continue;
    }
    const double t = std::clamp(depth.pixels[i] / depth_scale / 5.0, 0.0, 1.0);  // 0..5 m
    img.pixels[i] = Rgb{channel(1.5 - std::abs(4.0 * t - 3.0)), channel(1.5 - std::abs(4.0 * t - 2.0)),
                        channel(1.5 - std::abs(4.0 * t - 1.0))};
  }
  return img;
}

}  // namespace chronomap
