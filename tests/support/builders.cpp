#include "builders.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace chronomap::test {

VoxelKey at(int x, int y, int z, int origin) {
  return VoxelKey{static_cast<uint16_t>(origin + x), static_cast<uint16_t>(origin + y), static_cast<uint16_t>(origin + z)};
}

bool samePools(const SessionMap& a, const SessionMap& b) {
  const SessionMap::Pools pa = a.pools(), pb = b.pools();
  return pa.inner == pb.inner && pa.leaves == pb.leaves;
}

VoxelCounters freeVoxel(float length) {
  VoxelCounters c;
  c.length_m = length;
  return c;
}

VoxelCounters occupiedVoxel(Rgb colour, uint32_t hits) {
  VoxelCounters c;
  c.length_m = 0.025f * static_cast<float>(hits);
  c.hits = hits;
  c.red = colour.r * hits;
  c.green = colour.g * hits;
  c.blue = colour.b * hits;
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

SessionMap randomTileRegionSession(std::mt19937_64& rng, std::vector<uint8_t>& world, bool far_parts) {
  constexpr int kLo = kTileRegionLo, kHi = kTileRegionHi, kSide = kHi - kLo;
  for (int i = 0; i < 40; ++i) world[rng() % world.size()] ^= 1;
  SessionMap m(0.05);
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = kLo + static_cast<int>(rng() % 6);
    hi[a] = std::min(kHi, lo[a] + 4 + static_cast<int>(rng() % 12));
  }
  for (int z = lo[2]; z < hi[2]; ++z) {
    for (int y = lo[1]; y < hi[1]; ++y) {
      for (int x = lo[0]; x < hi[0]; ++x) {
        if (rng() % 12 == 0) continue;
        const bool occ = world[static_cast<size_t>(((z - kLo) * kSide + (y - kLo)) * kSide + (x - kLo))] != 0;
        m.add(at(x, y, z),
              occ ? occupiedVoxelExact(1 + static_cast<uint32_t>(rng() % 3), static_cast<uint8_t>(rng() % 256))
                  : freeVoxel(0.125f * static_cast<float>(1 + rng() % 4)));
      }
    }
  }
  if (rng() % 3 == 0) m.addCube(at(16, 0, 0), 4, freeVoxel(0.25f * static_cast<float>(1 + rng() % 3)));
  if (far_parts) {
    if (rng() % 3 == 0) m.addCube(at(32, 0, 0), 5, freeVoxel(0.5f));
    if (rng() % 3 == 0) m.add(at(40 + static_cast<int>(rng() % 8), 3, 5), occupiedVoxelExact(2, 9));
  }
  if (rng() % 2 == 0) m.compressFree();
  return m;
}

SessionMap changesScene(bool later) {
  struct Box {
    int x0, x1, y0, y1, z0, z1;  // inclusive
    Rgb colour;
    bool contains(int x, int y, int z) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1 && z >= z0 && z <= z1; }
  };
  const Box wall{34, 34, 0, 15, 0, 9, Rgb{128, 128, 128}};
  const std::vector<Box> boxes =
      later ? std::vector<Box>{wall,
                               {12, 14, 2, 4, 1, 8, Rgb{40, 40, 200}},
                               {20, 22, 10, 12, 1, 3, Rgb{40, 200, 40}},
                               {12, 13, 12, 13, 1, 2, Rgb{200, 200, 40}},
                               {31, 31, 5, 9, 3, 7, Rgb{150, 150, 150}}}
            : std::vector<Box>{wall, {2, 5, 2, 5, 1, 4, Rgb{200, 40, 40}}, {2, 4, 10, 12, 1, 3, Rgb{40, 200, 40}}};
  SessionMap s(0.05);
  for (int z = 0; z < 10; ++z) {
    for (int y = 0; y < 16; ++y) {
      for (int x = 0; x < 36; ++x) {
        const Box* in = nullptr;
        for (const Box& b : boxes) {
          if (b.contains(x, y, z)) in = &b;
        }
        s.add(at(x, y, z), in ? occupiedVoxel(in->colour) : freeVoxel());
      }
    }
  }
  return s;
}

Eigen::Isometry3d cameraLooking(const Eigen::Vector3d& position, double yaw, double pitch) {
  const Eigen::Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = forward.cross(right);
  T.linear().col(2) = forward;
  T.translation() = position;
  return T;
}

}  // namespace chronomap::test
