#include "builders.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace chronomap::test {

VoxelKey at(int x, int y, int z) {
  return VoxelKey{static_cast<uint16_t>(kKeyOrigin + x), static_cast<uint16_t>(kKeyOrigin + y),
                  static_cast<uint16_t>(kKeyOrigin + z)};
}

VoxelCounters freeVoxel(float length) {
  VoxelCounters c;
  c.length_m = length;
  return c;
}

VoxelCounters occupiedVoxel(Rgb color, uint32_t hits) {
  VoxelCounters c;
  c.length_m = 0.025f * static_cast<float>(hits);
  c.hits = hits;
  c.red = color.r * hits;
  c.green = color.g * hits;
  c.blue = color.b * hits;
  return c;
}

VoxelCounters occupiedVoxelExact(uint32_t hits, uint8_t red) {
  VoxelCounters c;
  c.length_m = 0.0625f * static_cast<float>(hits);
  c.hits = hits;
  c.red = uint32_t{red} * hits;
  c.green = 10 * hits;
  c.blue = 20 * hits;
  return c;
}

bool nearlyEqual(const VoxelCounters& a, const VoxelCounters& b) {
  return std::abs(a.length_m - b.length_m) <= 1e-5f * std::max(1.0f, std::abs(a.length_m)) && a.hits == b.hits &&
         a.red == b.red && a.green == b.green && a.blue == b.blue;
}

SessionMap wallSession(int wall_x, int first_free_x) {
  SessionMap m(0.05);
  for (int z = 0; z < 16; ++z) {
    for (int y = 0; y < 16; ++y) {
      for (int x = first_free_x; x < wall_x; ++x) m.add(at(x, y, z), freeVoxel());
      m.add(at(wall_x, y, z), occupiedVoxel(Rgb{static_cast<uint8_t>(16 * y), static_cast<uint8_t>(16 * z), 128}));
    }
  }
  return m;
}

SessionMap randomSessionMap(uint64_t seed, int side, double occupied, double resolution_m) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::mt19937 position(static_cast<uint32_t>(seed * 7 + 1));  // its own stream: the rest stays as it was
  SessionMap m(resolution_m);
  for (int z = 0; z < side; ++z) {
    for (int y = 0; y < side; ++y) {
      for (int x = 0; x < side; ++x) {
        if (u(rng) > 0.9) continue;
        VoxelCounters c;
        c.length_m = 0.125f;
        if (u(rng) < occupied) {
          c.hits = 2;
          c.red = 2 * static_cast<uint32_t>(rng() % 256);
          for (float& o : c.offset) o = 2.0f * (static_cast<float>(position() % 101) / 100.0f - 0.5f);
        }
        m.add(at(x, y, z), c);
      }
    }
  }
  m.compressFree();
  return m;
}

PointCloud cloudOf(std::initializer_list<Eigen::Vector3f> points) {
  PointCloud c;
  c.points.assign(points.begin(), points.end());
  c.width = static_cast<uint32_t>(c.points.size());
  return c;
}

}  // namespace chronomap::test
