#include "chronomap/render/top_view.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "chronomap/core/error.h"
#include "chronomap/render/draw.h"

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

ImageRgb renderTopView(const SessionMap& map, const TopViewSettings& settings) {
  if (map.empty()) throw DataError("the map is empty: nothing to draw");
  int lo[2] = {kKeysPerAxis, kKeysPerAxis}, hi[2] = {-1, -1};
  int zlo = kKeysPerAxis, zhi = -1;
  map.forEachLeaf([&](const LeafView& l) {
    const int side = 1 << l.level;
    lo[0] = std::min(lo[0], int{l.key.x});
    lo[1] = std::min(lo[1], int{l.key.y});
    hi[0] = std::max(hi[0], l.key.x + side - 1);
    hi[1] = std::max(hi[1], l.key.y + side - 1);
    if (l.counters.state() == VoxelState::Occupied) {
      zlo = std::min(zlo, int{l.key.z});
      zhi = std::max(zhi, int{l.key.z});
    }
  });
  const int ppv = std::max(1, settings.pixels_per_voxel);
  const int nx = hi[0] - lo[0] + 1, ny = hi[1] - lo[1] + 1;
  if (static_cast<int64_t>(nx) * ppv > 8192 || static_cast<int64_t>(ny) * ppv > 8192) {
    throw DataError("the map is too large for a top view at this scale (" + std::to_string(nx) + " x " +
                    std::to_string(ny) + " voxels)");
  }
  // Per column: highest occupied voxel (z, colour) or "free seen".
  std::vector<int> top(static_cast<size_t>(nx) * ny, -1);
  std::vector<Rgb> colour(top.size());
  std::vector<uint8_t> seen(top.size(), 0);
  map.forEachLeaf([&](const LeafView& l) {
    const VoxelState st = l.counters.state();
    if (st == VoxelState::Unknown) return;
    const int side = 1 << l.level;
    for (int dy = 0; dy < side; ++dy) {
      for (int dx = 0; dx < side; ++dx) {
        const size_t i = static_cast<size_t>(l.key.y + dy - lo[1]) * nx + (l.key.x + dx - lo[0]);
        seen[i] = 1;
        if (st == VoxelState::Occupied && int{l.key.z} > top[i]) {
          top[i] = l.key.z;
          colour[i] = l.counters.meanColour();
        }
      }
    }
  });
  ImageRgb img;
  img.width = static_cast<uint32_t>(nx * ppv);
  img.height = static_cast<uint32_t>(ny * ppv);
  img.pixels.resize(size_t{img.width} * img.height);
  const double zrange = std::max(1, zhi - zlo);
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      const size_t i = static_cast<size_t>(y) * nx + x;
      Rgb c = seen[i] ? settings.free_colour : settings.unknown_colour;
      if (top[i] >= 0) {
        const double shade = 0.55 + 0.45 * (top[i] - zlo) / zrange;  // higher is brighter
        c = Rgb{static_cast<uint8_t>(colour[i].r * shade), static_cast<uint8_t>(colour[i].g * shade),
                static_cast<uint8_t>(colour[i].b * shade)};
      }
      for (int py = 0; py < ppv; ++py) {
        const size_t row = static_cast<size_t>(ny - 1 - y) * static_cast<size_t>(ppv) + static_cast<size_t>(py);  // y up
        for (int px = 0; px < ppv; ++px) img.pixels[row * img.width + static_cast<size_t>(x * ppv + px)] = c;
      }
    }
  }
  return img;
}

ImageRgb renderChangeView(const SessionMap& background, const DiffMap& diff, const Segmentation& segmentation,
                          const TopViewSettings& settings) {
  ImageRgb img = renderTopView(background, settings);
  // The same frame as renderTopView: the key bounds of the background's leaves, y up.
  int lo_x = kKeysPerAxis, lo_y = kKeysPerAxis, hi_y = -1;
  background.forEachLeaf([&](const LeafView& l) {
    lo_x = std::min(lo_x, int{l.key.x});
    lo_y = std::min(lo_y, int{l.key.y});
    hi_y = std::max(hi_y, l.key.y + (1 << l.level) - 1);
  });
  const int ppv = std::max(1, settings.pixels_per_voxel);
  for (Rgb& p : img.pixels) {  // fade the background so that the changes stand out
    p = Rgb{static_cast<uint8_t>(160 + p.r * 3 / 8), static_cast<uint8_t>(160 + p.g * 3 / 8),
            static_cast<uint8_t>(160 + p.b * 3 / 8)};
  }
  auto toPixel = [&](int kx, int ky) {
    return std::pair<int, int>{(kx - lo_x) * ppv, (hi_y - ky) * ppv};
  };
  auto inside = [&](int x, int y) { return x >= 0 && y >= 0 && x < int(img.width) && y < int(img.height); };
  for (const Component& c : segmentation.components) {
    const Rgb colour = c.kind == ChangeKind::Appeared ? Rgb{20, 150, 40} : Rgb{210, 40, 30};
    for (uint32_t idx : c.cells) {
      const ChangeCell& cell = diff.cells()[idx];
      const int side = 1 << cell.level;
      const auto [x0, y0] = toPixel(cell.key.x, cell.key.y + side - 1);
      for (int y = y0; y < y0 + side * ppv; ++y) {
        for (int x = x0; x < x0 + side * ppv; ++x) {
          if (inside(x, y)) img.pixels[static_cast<size_t>(y) * img.width + static_cast<size_t>(x)] = colour;
        }
      }
    }
  }
  for (const Component& c : segmentation.components) {
    const Rgb colour = c.kind == ChangeKind::Appeared ? Rgb{10, 90, 20} : Rgb{140, 20, 10};
    const auto lo = diff.grid().keyOf(c.bbox_min_m + Eigen::Vector3d::Constant(diff.resolution_m() / 2));
    const auto hi = diff.grid().keyOf(c.bbox_max_m - Eigen::Vector3d::Constant(diff.resolution_m() / 2));
    if (!lo || !hi) continue;
    const auto [x0, y0] = toPixel(lo->x, hi->y);
    const auto [x1, y1] = toPixel(hi->x + 1, lo->y - 1);
    const int m = 2;  // margin around the component
    drawLine(img, x0 - m, y0 - m, x1 + m, y0 - m, colour);
    drawLine(img, x0 - m, y1 + m, x1 + m, y1 + m, colour);
    drawLine(img, x0 - m, y0 - m, x0 - m, y1 + m, colour);
    drawLine(img, x1 + m, y0 - m, x1 + m, y1 + m, colour);
    drawText(img, x1 + m + 2, y0 - m, std::to_string(c.id), colour, 2);
  }
  return img;
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
