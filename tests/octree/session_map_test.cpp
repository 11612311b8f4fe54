#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>
#include <tuple>
#include <optional>
#include <random>
#include <set>

#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/octree/voxel_queries.h"
#include "chronomap/store/cmap.h"
#include "builders.h"

namespace chronomap {
namespace {

using test::at;
using test::freeVoxel;
using test::nearlyEqual;
using test::occupiedVoxel;

VoxelCounters hit(float length, uint32_t hits, uint8_t r = 0) {
  VoxelCounters c;
  c.length_m = length;
  c.hits = hits;
  c.red = r * hits;
  return c;
}

TEST(SessionMap, UnobservedVoxelsAreUnknown) {
  SessionMap m(0.1);
  EXPECT_TRUE(m.empty());
  EXPECT_FALSE(m.find({100, 100, 100}).has_value());
  EXPECT_EQ(m.stateOf({100, 100, 100}), VoxelState::Unknown);
}

TEST(SessionMap, AddAccumulatesCounters) {
  SessionMap m(0.1);
  m.add({5, 6, 7}, hit(0.05f, 1, 100));
  m.add({5, 6, 7}, hit(0.02f, 2, 100));
  auto c = m.find({5, 6, 7});
  ASSERT_TRUE(c);
  EXPECT_FLOAT_EQ(c->length_m, 0.07f);
  EXPECT_EQ(c->hits, 3u);
  EXPECT_EQ(c->meanColour().r, 100);
  EXPECT_EQ(m.stateOf({5, 6, 7}), VoxelState::Occupied);
  EXPECT_EQ(m.stateOf({5, 6, 8}), VoxelState::Unknown);
  EXPECT_EQ(m.leafCount(), 1u);
  EXPECT_EQ(m.innerCount(), static_cast<size_t>(kTreeDepth));  // root + one node per level above unit
}

TEST(SessionMap, OccupiedCentresAndKnownBounds) {
  SessionMap m(0.1);
  EXPECT_FALSE(knownBounds(m).has_value());
  EXPECT_TRUE(occupiedCentres(m).centers_m.empty());
  m.add(at(1, 2, 3), occupiedVoxel(Rgb{200, 0, 0}));
  m.add(at(0, 0, 0), occupiedVoxel(Rgb{0, 0, 0}));
  m.add(at(-2, 0, 0), freeVoxel());
  m.addCube(at(4, 4, 4), 2, freeVoxel(3.2f));  // a compressed free cube of 4 x 4 x 4 voxels
  const VoxelCentres occupied = occupiedCentres(m);
  ASSERT_EQ(occupied.centers_m.size(), 2u);
  ASSERT_EQ(occupied.colours.size(), 2u);
  EXPECT_TRUE(occupied.centers_m[0].isApprox(Eigen::Vector3d(0.05, 0.05, 0.05)));  // Morton order
  EXPECT_TRUE(occupied.centers_m[1].isApprox(Eigen::Vector3d(0.15, 0.25, 0.35)));
  EXPECT_EQ(occupied.colours[1].r, 200);
  const auto bounds = knownBounds(m);
  ASSERT_TRUE(bounds);
  EXPECT_TRUE(bounds->min_m.isApprox(Eigen::Vector3d(-0.2, 0.0, 0.0)));
  EXPECT_TRUE(bounds->max_m.isApprox(Eigen::Vector3d(0.8, 0.8, 0.8)));
  // The free leaves: the unit voxel, then the 4-voxel cube as one entry at its centre.
  const FreeLeaves free = freeLeaves(m);
  ASSERT_EQ(free.centers_m.size(), 2u);
  ASSERT_EQ(free.sizes_m.size(), 2u);
  EXPECT_TRUE(free.centers_m[0].isApprox(Eigen::Vector3d(-0.15, 0.05, 0.05)));
  EXPECT_NEAR(free.sizes_m[0], 0.1, 1e-12);
  EXPECT_TRUE(free.centers_m[1].isApprox(Eigen::Vector3d(0.6, 0.6, 0.6)));
  EXPECT_NEAR(free.sizes_m[1], 0.4, 1e-12);
}

/// Property test: random updates in random batch orders equal a plain std::map reference.
TEST(SessionMap, AddManyMatchesAReferenceOnRandomUpdates) {
  for (uint64_t seed = 0; seed < 20; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> coord(1000, 1040);
    std::uniform_int_distribution<int> small(0, 3);
    SessionMap single(0.05), batched(0.05);
    std::map<VoxelKey, VoxelCounters> ref;
    std::vector<VoxelKey> keys;
    std::vector<VoxelCounters> deltas;
    for (int i = 0; i < 3000; ++i) {
      const VoxelKey k{static_cast<uint16_t>(coord(rng)), static_cast<uint16_t>(coord(rng)),
                       static_cast<uint16_t>(coord(rng))};
      const VoxelCounters d = hit(0.01f * static_cast<float>(small(rng) + 1), static_cast<uint32_t>(small(rng)));
      single.add(k, d);
      ref[k] += d;
      keys.push_back(k);
      deltas.push_back(d);
      if (small(rng) == 0) {  // flush a random-sized batch
        batched.addMany(keys, deltas);
        keys.clear();
        deltas.clear();
      }
    }
    batched.addMany(keys, deltas);
    ASSERT_EQ(single.leafCount(), ref.size());
    for (const auto& [k, c] : ref) {
      auto a = single.find(k);
      auto b = batched.find(k);
      ASSERT_TRUE(a && b);
      EXPECT_NEAR(a->length_m, c.length_m, 1e-5);
      EXPECT_EQ(a->hits, c.hits);
      EXPECT_EQ(*a, *b);
    }
    EXPECT_TRUE(single == batched);
    // Iteration visits each leaf once, in Morton order.
    std::vector<uint64_t> codes;
    single.forEachLeaf([&](const LeafView& l) { codes.push_back(mortonEncode(l.key)); });
    EXPECT_EQ(codes.size(), ref.size());
    EXPECT_TRUE(std::is_sorted(codes.begin(), codes.end()));
  }
}

TEST(SessionMap, CompressionMergesKnownFreeSubtreesAndKeepsSums) {
  SessionMap m(0.1);
  // A fully free aligned 4x4x4 block (levels 0..2) and one occupied voxel next to it.
  double total = 0.0;
  for (uint16_t x = 8; x < 12; ++x) {
    for (uint16_t y = 8; y < 12; ++y) {
      for (uint16_t z = 8; z < 12; ++z) {
        const float l = 0.01f * static_cast<float>(1 + x + y + z);
        m.add({x, y, z}, freeVoxel(l));
        total += l;
      }
    }
  }
  m.add({12, 8, 8}, hit(0.05f, 3));
  const size_t before = m.leafCount();
  const size_t removed = m.compressFree();
  EXPECT_EQ(before, 65u);
  EXPECT_EQ(removed, 63u);  // 64 free voxels became one level-2 node
  EXPECT_EQ(m.leafCount(), 2u);
  auto leaf = m.findLeaf({9, 10, 11});
  ASSERT_TRUE(leaf);
  EXPECT_EQ(leaf->level, 2);
  EXPECT_EQ(leaf->key, (VoxelKey{8, 8, 8}));
  EXPECT_NEAR(leaf->counters.length_m, total, 1e-4);
  // A unit look-up inside gets an even share; states are unchanged.
  auto unit = m.find({9, 10, 11});
  ASSERT_TRUE(unit);
  EXPECT_NEAR(unit->length_m, total / 64.0, 1e-6);
  EXPECT_EQ(m.stateOf({9, 10, 11}), VoxelState::Free);
  EXPECT_EQ(m.stateOf({12, 8, 8}), VoxelState::Occupied);
  const SessionMapCounts c = m.counts();
  EXPECT_EQ(c.free_voxels, 64u);
  EXPECT_EQ(c.occupied_voxels, 1u);
  EXPECT_EQ(c.compressed_leaves, 1u);
}

TEST(SessionMap, CompressionNeverMergesHitsOrUnknown) {
  SessionMap m(0.1);
  for (uint16_t i = 0; i < 8; ++i) {
    m.add({static_cast<uint16_t>(i & 1), static_cast<uint16_t>((i >> 1) & 1), static_cast<uint16_t>(i >> 2)},
          freeVoxel(0.1f));
  }
  m.add({1, 1, 1}, hit(0.0f, 1));  // a free voxel with a hit: P = 1 - exp(-1/0.1) -> occupied
  for (uint16_t i = 0; i < 7; ++i) {
    m.add({static_cast<uint16_t>(10 + (i & 1)), static_cast<uint16_t>((i >> 1) & 1), static_cast<uint16_t>(i >> 2)},
          freeVoxel(0.1f));
  }
  EXPECT_EQ(m.compressFree(), 0u);  // first group has a hit, second misses a child
  EXPECT_EQ(m.leafCount(), 15u);
}

// compressFree() against a slow reference on random maps: level by level from the bottom, eight
// sibling leaves of one level, all known free without hits, become their parent's leaf with the
// sum of their lengths in slot order; the root's children stay. Maps are compressed two or three
// times with adds in between, so that compressed leaves are refined and compressed again.
TEST(SessionMap, CompressionMatchesASlowReferenceOnRandomMaps) {
  using Leaves = std::map<std::tuple<int, uint16_t, uint16_t, uint16_t>, VoxelCounters>;  // level, corner
  const auto leavesOf = [](const SessionMap& m) {
    Leaves out;
    m.forEachLeaf([&](const LeafView& l) { out[{l.level, l.key.x, l.key.y, l.key.z}] = l.counters; });
    return out;
  };
  const auto reference = [](Leaves leaves) {
    for (int level = 1; level < kTreeDepth; ++level) {
      std::map<std::tuple<uint16_t, uint16_t, uint16_t>, std::map<int, VoxelCounters>> children;
      for (const auto& [k, c] : leaves) {
        if (std::get<0>(k) != level - 1) continue;
        const VoxelKey key{std::get<1>(k), std::get<2>(k), std::get<3>(k)};
        const VoxelKey parent = cellCorner(key, level);
        children[{parent.x, parent.y, parent.z}][childSlot(key, level - 1)] = c;
      }
      for (const auto& [p, slots] : children) {
        if (slots.size() != 8) continue;
        bool all_free = true;
        for (const auto& [slot, c] : slots) all_free = all_free && c.isKnownFreeWithoutHits();
        if (!all_free) continue;
        VoxelCounters sum;
        for (const auto& [slot, c] : slots) sum.length_m += c.length_m;  // slots in order
        for (const auto& [slot, c] : slots) {
          const VoxelKey child{static_cast<uint16_t>(std::get<0>(p) + ((slot & 1) << (level - 1))),
                               static_cast<uint16_t>(std::get<1>(p) + (((slot >> 1) & 1) << (level - 1))),
                               static_cast<uint16_t>(std::get<2>(p) + (((slot >> 2) & 1) << (level - 1)))};
          leaves.erase({level - 1, child.x, child.y, child.z});
        }
        leaves[{level, std::get<0>(p), std::get<1>(p), std::get<2>(p)}] = sum;
      }
    }
    return leaves;
  };
  int merged_groups = 0;
  for (uint32_t seed = 1; seed <= 40; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> coord(0, 15), size_bits(0, 3), kind(0, 19);
    std::uniform_real_distribution<float> length(0.001f, 0.2f);
    SessionMap m(0.1);
    const int rounds = 2 + static_cast<int>(seed % 2);
    for (int round = 0; round < rounds; ++round) {
      for (int block = 0; block < 12; ++block) {
        // A random aligned block filled with free voxels (sometimes one short), with a hit or
        // a zero length now and then.
        const int side = 1 << size_bits(rng);
        const int x0 = coord(rng) / side * side, y0 = coord(rng) / side * side, z0 = coord(rng) / side * side;
        const bool one_short = kind(rng) == 0;
        for (int x = x0; x < x0 + side; ++x) {
          for (int y = y0; y < y0 + side; ++y) {
            for (int z = z0; z < z0 + side; ++z) {
              if (one_short && x == x0 && y == y0 && z == z0) continue;
              const VoxelKey key{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)};
              const int k = kind(rng);
              VoxelCounters c = k == 1 ? hit(length(rng), 1, 9) : k == 2 ? freeVoxel(0.0f) : freeVoxel(length(rng));
              if (k == 3) c.offset[1] = -0.0f;  // free without hits, yet not free-only: the full pool
              m.add(key, c);
            }
          }
        }
      }
      const Leaves before = leavesOf(m);
      const Leaves want = reference(before);
      merged_groups += static_cast<int>(before.size() - want.size());
      const size_t count_before = m.leafCount();  // garbage slots included
      EXPECT_EQ(m.compressFree(), count_before - want.size());
      const Leaves got = leavesOf(m);
      ASSERT_EQ(got.size(), want.size()) << "seed " << seed << " round " << round;
      EXPECT_EQ(m.leafCount(), want.size());  // nothing left behind
      // Each leaf in the pool that fits it, and the inner nodes exactly the leaves' ancestors.
      size_t free_only = 0;
      std::set<std::tuple<int, uint16_t, uint16_t, uint16_t>> ancestors;
      for (const auto& [k, c] : want) {
        free_only += (c.hits | c.red | c.green | c.blue | std::bit_cast<uint32_t>(c.offset[0]) |
                      std::bit_cast<uint32_t>(c.offset[1]) | std::bit_cast<uint32_t>(c.offset[2])) == 0;
        const VoxelKey key{std::get<1>(k), std::get<2>(k), std::get<3>(k)};
        for (int level = std::get<0>(k) + 1; level <= kTreeDepth; ++level) {
          const VoxelKey corner = cellCorner(key, level);
          ancestors.insert({level, corner.x, corner.y, corner.z});
        }
      }
      EXPECT_EQ(m.innerCount(), ancestors.size());
      EXPECT_EQ(m.memoryBytes(), sizeof(SessionMap) + ancestors.size() * sizeof(SessionMap::Children) +
                                     (want.size() - free_only) * sizeof(VoxelCounters) + free_only * sizeof(float));
      for (const auto& [k, c] : want) {
        const auto it = got.find(k);
        ASSERT_NE(it, got.end()) << "seed " << seed << " level " << std::get<0>(k);
        EXPECT_TRUE(it->second == c) << "seed " << seed;
        EXPECT_EQ(std::bit_cast<uint32_t>(it->second.length_m), std::bit_cast<uint32_t>(c.length_m));
      }
    }
  }
  EXPECT_GT(merged_groups, 500);  // the random maps do compress
}

TEST(SessionMap, RefiningACompressedNodeSplitsItEvenly) {
  SessionMap m(0.1);
  for (uint16_t x = 0; x < 2; ++x) {
    for (uint16_t y = 0; y < 2; ++y) {
      for (uint16_t z = 0; z < 2; ++z) m.add({x, y, z}, freeVoxel(0.1f));
    }
  }
  ASSERT_EQ(m.compressFree(), 7u);
  m.add({1, 0, 1}, hit(0.02f, 1, 50));
  EXPECT_EQ(m.leafCount(), 8u);
  auto changed = m.find({1, 0, 1});
  ASSERT_TRUE(changed);
  EXPECT_NEAR(changed->length_m, 0.1f + 0.02f, 1e-6);
  EXPECT_EQ(changed->hits, 1u);
  for (uint16_t x = 0; x < 2; ++x) {
    for (uint16_t y = 0; y < 2; ++y) {
      for (uint16_t z = 0; z < 2; ++z) {
        if (x == 1 && y == 0 && z == 1) continue;
        EXPECT_NEAR(m.find({x, y, z})->length_m, 0.1f, 1e-6);
      }
    }
  }
}

// Leaves rays only crossed keep their length alone (4 bytes, not 32); a hit moves the leaf to
// the pool of whole counters, with the sums the whole counters would have had, bit for bit.
TEST(SessionMap, FreeLeavesHoldOnlyALengthAndMoveWhenHit) {
  SessionMap m(0.05);
  constexpr uint16_t kVoxels = 1000;
  const auto key = [](uint16_t i) { return VoxelKey{static_cast<uint16_t>(2 * i), 0, 0}; };  // no 8 siblings
  const auto length = [](uint16_t i) { return 0.01f * static_cast<float>(i % 37 + 1); };
  for (uint16_t i = 0; i < kVoxels; ++i) m.add(key(i), freeVoxel(length(i)));
  const auto bytes = [&](size_t full, size_t free) {
    return sizeof(SessionMap) + m.innerCount() * sizeof(SessionMap::Children) + full * sizeof(VoxelCounters) +
           free * sizeof(float);
  };
  EXPECT_EQ(m.memoryBytes(), bytes(0, kVoxels));
  const std::vector<uint8_t> before = encodeSessionMap(m, nlohmann::json::object());
  for (uint16_t i = 0; i < kVoxels; i += 100) m.add(key(i), hit(0.003f, 2, 90));
  EXPECT_EQ(m.leafCount(), kVoxels);
  EXPECT_EQ(m.memoryBytes(), bytes(10, kVoxels));  // the moved leaves' old slots until compressFree()
  for (uint16_t i = 0; i < kVoxels; ++i) {
    VoxelCounters want = freeVoxel(length(i));
    if (i % 100 == 0) want += hit(0.003f, 2, 90);
    const std::optional<VoxelCounters> got = m.find(key(i));
    ASSERT_TRUE(got && *got == want) << i;
    ASSERT_EQ(std::bit_cast<uint32_t>(got->length_m), std::bit_cast<uint32_t>(want.length_m)) << i;
  }
  const std::vector<uint8_t> with_moved = encodeSessionMap(m, nlohmann::json::object());
  EXPECT_EQ(m.compressFree(), 0u);
  EXPECT_EQ(m.memoryBytes(), bytes(10, kVoxels - 10));
  // Files hold the tree, not the pools' layout: the slots left behind change no byte.
  EXPECT_EQ(encodeSessionMap(m, nlohmann::json::object()), with_moved);
  EXPECT_NE(with_moved, before);
  // Counters that only look free (a negative zero offset) stay whole: they read back bit for bit.
  VoxelCounters signed_zero = freeVoxel(0.02f);
  signed_zero.offset[1] = -0.0f;
  m.add(key(kVoxels), signed_zero);
  EXPECT_TRUE(std::signbit(m.find(key(kVoxels))->offset[1]));
  EXPECT_EQ(m.memoryBytes(), bytes(11, kVoxels - 10));
}

// Every operation that writes counters (add, addMany, addCube, merge, assign), in random
// sequences that hit free leaves, move them to the whole counters, refine compressed cubes and
// forget voxels, against a dense reference of unit voxels. Lengths are binary fractions, so
// spreading a cube (a division by 8 a level) and the sums stay exact and the maps must agree bit
// for bit with the reference, whatever pool each leaf lies in.
TEST(SessionMap, EveryWriteMatchesADenseReferenceOnRandomSequences) {
  constexpr int kSide = 16;
  using Dense = std::map<VoxelKey, VoxelCounters>;
  const auto key = [](int x, int y, int z) { return at(x, y, z); };
  for (uint64_t seed = 1; seed <= 25; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> coord(0, kSide - 1), small(1, 8), pick(0, 99);
    const auto randomDelta = [&](bool free) {
      VoxelCounters d = freeVoxel(static_cast<float>(small(rng)) / 16.0f);
      if (free) return d;
      d.hits = static_cast<uint32_t>(small(rng));
      d.red = d.hits * 10;
      d.offset[pick(rng) % 3] = 0.25f * static_cast<float>(d.hits);
      return d;
    };
    // Adds a cube of `level` at a random aligned corner to a map and its reference.
    const auto addCube = [&](SessionMap& m, Dense& ref) {
      const int level = 1 + pick(rng) % 2, size = 1 << level;
      const int x = coord(rng) / size * size, y = coord(rng) / size * size, z = coord(rng) / size * size;
      const float length = static_cast<float>(small(rng)) * static_cast<float>(size * size * size) / 16.0f;
      m.addCube(key(x, y, z), level, freeVoxel(length));
      for (int dz = 0; dz < size; ++dz) {
        for (int dy = 0; dy < size; ++dy) {
          for (int dx = 0; dx < size; ++dx) ref[key(x + dx, y + dy, z + dz)] += freeVoxel(length / static_cast<float>(size * size * size));
        }
      }
    };
    SessionMap m(0.05);
    Dense ref;
    for (int op = 0; op < 400; ++op) {
      const int kind = pick(rng);
      if (kind < 50) {  // one voxel, free or hit
        const VoxelKey k = key(coord(rng), coord(rng), coord(rng));
        const VoxelCounters d = randomDelta(kind < 30);
        m.add(k, d);
        ref[k] += d;
      } else if (kind < 65) {
        addCube(m, ref);
      } else if (kind < 80) {  // a batch, with repeated keys
        std::vector<VoxelKey> keys;
        std::vector<VoxelCounters> deltas;
        for (int i = 0; i < 20; ++i) {
          keys.push_back(key(coord(rng) % 4, coord(rng), coord(rng) % 4));
          deltas.push_back(randomDelta(i % 3 != 0));
          ref[keys.back()] += deltas.back();
        }
        m.addMany(keys, deltas);
      } else if (kind < 90) {  // another map merged in
        SessionMap other(0.05);
        Dense other_ref;
        addCube(other, other_ref);
        for (int i = 0; i < 5; ++i) {
          const VoxelKey k = key(coord(rng), coord(rng), coord(rng));
          const VoxelCounters d = randomDelta(i % 2 == 0);
          other.add(k, d);
          other_ref[k] += d;
        }
        m.merge(other);
        for (const auto& [k, c] : other_ref) ref[k] += c;
      } else {  // a voxel set or forgotten
        const VoxelKey k = key(coord(rng), coord(rng), coord(rng));
        if (kind < 95) {
          m.assign(k, std::nullopt);
          ref.erase(k);
        } else {
          const VoxelCounters v = randomDelta(kind < 97);
          m.assign(k, v);
          ref[k] = v;
        }
      }
    }
    size_t voxels = 0;
    for (int z = 0; z < kSide; ++z) {
      for (int y = 0; y < kSide; ++y) {
        for (int x = 0; x < kSide; ++x) {
          const auto it = ref.find(key(x, y, z));
          const std::optional<VoxelCounters> got = m.find(key(x, y, z));
          ASSERT_EQ(got.has_value(), it != ref.end()) << "seed " << seed << " at " << x << "," << y << "," << z;
          if (!got) continue;
          ++voxels;
          ASSERT_EQ(*got, it->second) << "seed " << seed << " at " << x << "," << y << "," << z;
        }
      }
    }
    EXPECT_EQ(voxels, ref.size());
    // The file holds the tree whatever the pools' layout: the pools laid out again write the same
    // bytes, and they read back as the map.
    SessionMap::Pools pools = m.pools();
    SessionMap copy(0.05);
    copy.assignPools(std::move(pools.inner), std::move(pools.leaves));
    const std::vector<uint8_t> bytes = encodeSessionMap(m, nlohmann::json::object());
    EXPECT_EQ(encodeSessionMap(copy, nlohmann::json::object()), bytes) << "seed " << seed;
    EXPECT_TRUE(sessionMapFrom(decodeCmap(bytes, "m.cmap"), "m.cmap") == asStored(m)) << "seed " << seed;
  }
}

TEST(SessionMap, RefinementThroughSeveralLevels) {
  SessionMap m(0.1);
  for (uint16_t x = 0; x < 8; ++x)
    for (uint16_t y = 0; y < 8; ++y)
      for (uint16_t z = 0; z < 8; ++z) m.add({x, y, z}, freeVoxel(0.08f));
  m.compressFree();
  ASSERT_EQ(m.leafCount(), 1u);
  m.add({5, 2, 7}, freeVoxel(0.01f));
  // One split per level: 3 levels x 8 children, minus the reused slots.
  EXPECT_EQ(m.leafCount(), 22u);
  EXPECT_NEAR(m.find({5, 2, 7})->length_m, 0.09f, 1e-6);
  EXPECT_NEAR(m.find({0, 0, 0})->length_m, 0.08f, 1e-6);
  double sum = 0.0;
  m.forEachLeaf([&](const LeafView& l) { sum += l.counters.length_m; });
  EXPECT_NEAR(sum, 512 * 0.08 + 0.01, 1e-3);
}

TEST(SessionMap, AssignPoolsRejectsInvalidTrees) {
  using C = SessionMap::Children;
  auto empty = [] {
    C c;
    c.fill(SessionMap::kEmpty);
    return c;
  };
  SessionMap m(0.1);
  EXPECT_THROW(m.assignPools({}, {}), FormatError);
  std::vector<C> inner{empty()};
  inner[0][0] = 5;  // dangling inner reference
  EXPECT_THROW(m.assignPools(inner, {}), FormatError);
  inner[0][0] = 0;  // cycle to the root
  EXPECT_THROW(m.assignPools(inner, {}), FormatError);
  inner[0][0] = SessionMap::kLeafBit | 0u;  // leaf at level 15 must be known-free
  EXPECT_THROW(m.assignPools(inner, {hit(1.0f, 1)}), FormatError);
  EXPECT_NO_THROW(m.assignPools(inner, {freeVoxel(1.0f)}));
  inner[0][1] = SessionMap::kLeafBit | 0u;  // the same leaf twice
  EXPECT_THROW(m.assignPools(inner, {freeVoxel(1.0f)}), FormatError);
  inner[0][1] = SessionMap::kEmpty;
  EXPECT_THROW(m.assignPools(inner, {freeVoxel(1.0f), freeVoxel(1.0f)}), FormatError);  // unreachable leaf
  EXPECT_THROW(m.assignPools(inner, {freeVoxel(std::nanf(""))}), FormatError);
  inner[0][0] = SessionMap::kLeafBit | 0x40000000u;  // bit 30 set: past the end, not leaf 0
  EXPECT_THROW(m.assignPools(inner, {freeVoxel(1.0f)}), FormatError);
}

// ---------------------------------------------------------------------------------------------
// SessionMap building blocks

TEST(SessionMapMerge, SumsCountersAndSpreadsCompressedNodesEvenly) {
  SessionMap coarse(0.05), fine(0.05);
  coarse.addCube(at(0, 0, 0), 2, freeVoxel(6.4f));  // 64 voxels, 0.1 m each
  fine.add(at(1, 2, 3), occupiedVoxel({10, 20, 30}, 4));
  fine.add(at(5, 0, 0), freeVoxel(0.5f));  // outside the cube
  SessionMap sum = coarse;
  sum.merge(fine);
  for (int z = 0; z < 4; ++z) {
    for (int y = 0; y < 4; ++y) {
      for (int x = 0; x < 4; ++x) {
        VoxelCounters expected = freeVoxel(0.1f);
        if (x == 1 && y == 2 && z == 3) expected += occupiedVoxel({10, 20, 30}, 4);
        ASSERT_TRUE(sum.find(at(x, y, z)));
        EXPECT_TRUE(nearlyEqual(*sum.find(at(x, y, z)), expected)) << x << y << z;
      }
    }
  }
  EXPECT_EQ(sum.find(at(5, 0, 0))->length_m, 0.5f);
  EXPECT_FALSE(sum.find(at(6, 0, 0)));
  // The other way round gives the same voxels.
  SessionMap other = fine;
  other.merge(coarse);
  for (int x = 0; x < 6; ++x) EXPECT_TRUE(nearlyEqual(*sum.find(at(x, 0, 0)), *other.find(at(x, 0, 0))));
}

TEST(SessionMapMerge, MergingAMapIntoItselfDoublesIt) {
  SessionMap m = test::randomSessionMap(3, 8);
  const SessionMap before = m;
  m.merge(m);
  before.forEachLeaf([&](const LeafView& l) {
    VoxelCounters twice = l.counters;
    twice += l.counters;
    const auto leaf = m.findLeaf(l.key);
    ASSERT_TRUE(leaf);
    EXPECT_EQ(leaf->level, l.level);
    EXPECT_EQ(leaf->counters, twice);
  });
}

TEST(SessionMapAssign, SetsAndForgetsVoxelsInsideCompressedNodes) {
  SessionMap m(0.05);
  m.addCube(at(0, 0, 0), 3, freeVoxel(51.2f));  // 512 voxels of 0.1 m
  m.assign(at(3, 3, 3), occupiedVoxel({1, 2, 3}));
  m.assign(at(4, 4, 4), std::nullopt);
  EXPECT_EQ(m.stateOf(at(3, 3, 3)), VoxelState::Occupied);
  EXPECT_EQ(m.stateOf(at(4, 4, 4)), VoxelState::Unknown);
  EXPECT_FLOAT_EQ(m.find(at(0, 0, 0))->length_m, 0.1f);
  EXPECT_FLOAT_EQ(m.find(at(7, 7, 7))->length_m, 0.1f);
  const SessionMapCounts c = m.counts();
  EXPECT_EQ(c.occupied_voxels, 1u);
  EXPECT_EQ(c.free_voxels, 510u);
  // Forgetting the only voxel of a branch leaves no empty inner nodes after compression.
  SessionMap single(0.05);
  single.add(at(9, 9, 9), occupiedVoxel({1, 1, 1}));
  single.assign(at(9, 9, 9), std::nullopt);
  single.compressFree();
  EXPECT_EQ(single.innerCount(), 1u);
  EXPECT_EQ(single.leafCount(), 0u);
}

TEST(SessionMapAddCube, RejectsBadCubes) {
  SessionMap m(0.05);
  EXPECT_THROW(m.addCube(at(1, 0, 0), 1, freeVoxel()), UsageError);  // not aligned
  EXPECT_THROW(m.addCube(at(0, 0, 0), kTreeDepth, freeVoxel()), UsageError);
  EXPECT_THROW(m.addCube(at(0, 0, 0), 2, occupiedVoxel({1, 1, 1})), UsageError);  // hits above unit level
  m.addCube(at(0, 0, 0), 2, VoxelCounters{});  // an unobserved cube adds nothing
  EXPECT_TRUE(m.empty());
}

// addCubes (coarse carving's merge) is addCube one cube after another, on a map that is finer
// in places, with repeated and zero-length cubes, in raster order and shuffled.
TEST(SessionMapAddCube, AddCubesIsAddCubeInALoop) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> cell(0, 15), fine(0, 63);
  SessionMap base(0.05);
  for (int i = 0; i < 200; ++i) base.add(at(fine(rng), fine(rng), fine(rng)), freeVoxel());
  std::vector<VoxelKey> corners;
  std::vector<float> lengths;
  for (int i = 0; i < 400; ++i) {
    corners.push_back(at(4 * cell(rng), 4 * cell(rng), 4 * cell(rng)));
    lengths.push_back(i % 7 == 0 ? 0.0f : 0.01f * static_cast<float>(i));
  }
  for (bool sorted : {true, false}) {
    if (sorted) {
      std::vector<size_t> order(corners.size());
      for (size_t i = 0; i < order.size(); ++i) order[i] = i;
      std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
        return std::tie(corners[a].z, corners[a].y, corners[a].x) < std::tie(corners[b].z, corners[b].y, corners[b].x);
      });
      std::vector<VoxelKey> c;
      std::vector<float> l;
      for (size_t i : order) {
        c.push_back(corners[i]);
        l.push_back(lengths[i]);
      }
      corners = c;
      lengths = l;
    } else {
      std::shuffle(corners.begin(), corners.end(), rng);
    }
    SessionMap many = base, loop = base;
    many.addCubes(corners, 2, lengths);
    for (size_t i = 0; i < corners.size(); ++i) {
      VoxelCounters c;
      c.length_m = lengths[i];
      loop.addCube(corners[i], 2, c);
    }
    EXPECT_TRUE(many == loop) << "sorted=" << sorted;
  }
  SessionMap m(0.05);
  const std::vector<VoxelKey> bad = {at(2, 0, 0)};
  const std::vector<float> one = {1.0f};
  EXPECT_THROW(m.addCubes(bad, 2, one), UsageError);  // not aligned
  EXPECT_THROW(m.addCubes(bad, 0, one), UsageError);  // unit level: addMany
  EXPECT_THROW(m.addCubes(bad, 1, {}), UsageError);   // lengths missing
}

}  // namespace
}  // namespace chronomap
