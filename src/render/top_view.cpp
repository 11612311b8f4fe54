#include "chronomap/render/top_view.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "chronomap/core/error.h"
#include "chronomap/render/draw.h"
#include "top_view_parts.h"

namespace chronomap {

ImageRgb renderCostmap(const Costmap& c) {
  ImageRgb img{static_cast<uint32_t>(c.width), static_cast<uint32_t>(c.height), {}};
  img.pixels.reserve(c.cost.size());
  for (int j = c.height - 1; j >= 0; --j) {
    for (int i = 0; i < c.width; ++i) {
      const int8_t v = c.at(i, j);
      if (v < 0) {
        img.pixels.push_back({128, 128, 128});
      } else if (v == Costmap::kLethal) {
        img.pixels.push_back({0, 0, 0});
      } else if (v == Costmap::kInscribed) {
        img.pixels.push_back({110, 20, 20});
      } else {
        const auto fade = static_cast<uint8_t>(255 - v * 2);
        img.pixels.push_back({255, fade, fade});
      }
    }
  }
  return img;
}

namespace render_detail {

namespace {

// The largest picture side in pixels.
constexpr int64_t kMaxSide_px = 8192;

/// The key bounds (x, y) of the columns to draw: the map's leaves, cut to the window.
void columnBounds(const SessionMap& map, const Eigen::AlignedBox2d& window_m, int lo[2], int hi[2]) {
  lo[0] = lo[1] = kKeysPerAxis;
  hi[0] = hi[1] = -1;
  map.forEachLeaf([&](const LeafView& l) {
    const int side = 1 << l.level;
    lo[0] = std::min(lo[0], int{l.key.x});
    lo[1] = std::min(lo[1], int{l.key.y});
    hi[0] = std::max(hi[0], l.key.x + side - 1);
    hi[1] = std::max(hi[1], l.key.y + side - 1);
  });
  if (window_m.isEmpty()) return;
  const KeyGrid& g = map.grid();
  const Eigen::Vector3d wlo = g.toKeySpace(Eigen::Vector3d(window_m.min().x(), window_m.min().y(), 0.0));
  const Eigen::Vector3d whi = g.toKeySpace(Eigen::Vector3d(window_m.max().x(), window_m.max().y(), 0.0));
  for (int a = 0; a < 2; ++a) {
    lo[a] = std::max(lo[a], static_cast<int>(std::floor(wlo[a])));
    hi[a] = std::min(hi[a], static_cast<int>(std::ceil(whi[a])) - 1);
  }
}

}  // namespace

Raster rasterOf(const SessionMap& map, const TopViewSettings& settings, const Eigen::AlignedBox2d& window_m) {
  if (map.empty()) throw DataError("the map is empty: nothing to draw");
  int lo[2], hi[2];
  columnBounds(map, window_m, lo, hi);
  if (hi[0] < lo[0] || hi[1] < lo[1]) throw DataError("the map has no column in the area to draw");
  const int ppv = std::max(1, settings.pixels_per_voxel);
  const int nx = hi[0] - lo[0] + 1, ny = hi[1] - lo[1] + 1;
  if (int64_t{nx} * ppv > kMaxSide_px || int64_t{ny} * ppv > kMaxSide_px) {
    throw DataError("the map is too large for a top view at this scale (" + std::to_string(nx) + " x " +
                    std::to_string(ny) + " voxels)");
  }
  // Per column: highest occupied voxel (z, colour) or "seen".
  std::vector<int> top(static_cast<size_t>(nx) * ny, -1);
  std::vector<Rgb> colour(top.size());
  std::vector<uint8_t> seen(top.size(), 0);
  int zlo = kKeysPerAxis, zhi = -1;
  map.forEachLeaf([&](const LeafView& l) {
    const VoxelState st = l.counters.state();
    if (st == VoxelState::Unknown) return;
    const int side = 1 << l.level;
    const int x0 = std::max(int{l.key.x}, lo[0]), x1 = std::min(l.key.x + side - 1, hi[0]);
    const int y0 = std::max(int{l.key.y}, lo[1]), y1 = std::min(l.key.y + side - 1, hi[1]);
    if (x0 > x1 || y0 > y1) return;
    if (st == VoxelState::Occupied) {
      zlo = std::min(zlo, int{l.key.z});
      zhi = std::max(zhi, int{l.key.z});
    }
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const size_t i = static_cast<size_t>(y - lo[1]) * nx + static_cast<size_t>(x - lo[0]);
        seen[i] = 1;
        if (st == VoxelState::Occupied && int{l.key.z} > top[i]) {
          top[i] = l.key.z;
          colour[i] = l.counters.meanColour();
        }
      }
    }
  });
  Raster r;
  ImageRgb& img = r.image;
  img.width = static_cast<uint32_t>(nx * ppv);
  img.height = static_cast<uint32_t>(ny * ppv);
  img.pixels.resize(size_t{img.width} * img.height);
  const double zrange = std::max(1, zhi - zlo);
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      const size_t i = static_cast<size_t>(y) * nx + static_cast<size_t>(x);
      Rgb c = seen[i] ? settings.free_colour : settings.unknown_colour;
      if (top[i] >= 0) {
        const double shade = 0.55 + 0.45 * (top[i] - zlo) / zrange;  // higher is brighter
        c = Rgb{static_cast<uint8_t>(colour[i].r * shade), static_cast<uint8_t>(colour[i].g * shade),
                static_cast<uint8_t>(colour[i].b * shade)};
      }
      fillRect(img, x * ppv, (ny - 1 - y) * ppv, (x + 1) * ppv, (ny - y) * ppv, c);  // y up
    }
  }
  const KeyGrid& g = map.grid();
  const double res = g.resolution_m();
  r.frame.x_min_m = (lo[0] - static_cast<double>(kKeyOrigin)) * res;
  r.frame.y_max_m = (hi[1] + 1 - static_cast<double>(kKeyOrigin)) * res;
  r.frame.metres_per_pixel = res / ppv;
  r.frame.width_px = static_cast<int>(img.width);
  r.frame.height_px = static_cast<int>(img.height);
  return r;
}

}  // namespace render_detail

TopView drawTopView(const SessionMap& map, const TopViewSettings& settings) {
  render_detail::Raster r = render_detail::rasterOf(map, settings);
  render_detail::drawAreaNames(r.image, r.frame, settings.areas, settings.area_name_colour);
  return render_detail::framed(std::move(r), settings,
                               render_detail::backgroundLegend(settings, [](Rgb c) { return c; }));
}

ImageRgb renderTopView(const SessionMap& map, const TopViewSettings& settings) {
  return drawTopView(map, settings).image;
}

ImageRgb renderPointsTopView(const std::vector<Eigen::Vector3f>& points, const std::vector<Rgb>& colours,
                             double metres_per_pixel) {
  if (points.empty()) throw DataError("no valid points to draw");
  Eigen::Vector3f lo = points[0], hi = points[0];
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  ImageRgb img;
  img.width = static_cast<uint32_t>(std::min(4000.0, std::ceil((hi.x() - lo.x()) / metres_per_pixel) + 1));
  img.height = static_cast<uint32_t>(std::min(4000.0, std::ceil((hi.y() - lo.y()) / metres_per_pixel) + 1));
  img.pixels.assign(size_t{img.width} * img.height, Rgb{255, 255, 255});
  std::vector<float> top(img.pixels.size(), -1e9f);
  for (size_t i = 0; i < points.size(); ++i) {
    const auto u = static_cast<int64_t>((points[i].x() - lo.x()) / metres_per_pixel);
    const auto v = static_cast<int64_t>((hi.y() - points[i].y()) / metres_per_pixel);
    if (u < 0 || v < 0 || u >= img.width || v >= img.height) continue;
    const size_t at = static_cast<size_t>(v) * img.width + static_cast<size_t>(u);
    if (points[i].z() > top[at]) {
      top[at] = points[i].z();
      img.pixels[at] = colours[i];
    }
  }
  return img;
}

}  // namespace chronomap
