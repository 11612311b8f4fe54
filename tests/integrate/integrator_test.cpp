#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <span>
#include <string>
#include <nlohmann/json.hpp>
#include <tuple>

#include "chronomap/core/error.h"
#include "chronomap/integrate/incremental.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/store/cmap.h"
#include "chronomap/sim/box_room.h"
#include "test_support.h"
#include "integrate/ray_accumulator.h"
#include "integrate/zero_pages.h"

namespace chronomap {
namespace {

/// The Kinect-like benchmark camera scaled down to `width` pixels (same field of view).
PinholeCamera smallCamera(uint32_t width) {
  PinholeCamera cam;
  const double scale = width / 640.0;
  cam.width = width;
  cam.height = static_cast<uint32_t>(480 * scale);
  cam.fx = cam.fy = 525.0 * scale;
  cam.cx = (cam.width - 1) / 2.0;
  cam.cy = (cam.height - 1) / 2.0;
  return cam;
}

IntegratorSettings exactUncompressed() {
  IntegratorSettings s;
  s.compress_free = false;
  s.threads = 1;
  return s;
}

Frame frameAt(const Eigen::Vector3d& origin, PointCloud cloud) {
  Frame f;
  f.T_world_sensor = Eigen::Isometry3d::Identity();
  f.T_world_sensor.translation() = origin;
  f.cloud = std::move(cloud);
  f.source = "test frame";
  return f;
}

TEST(Integrator, SingleAxisRayHasExactLengthsAndOneHit) {
  SessionMap map(0.1);
  // From the centre of voxel 0 to x = 0.98: voxel 0 gets 0.05 m, voxels 1..8 0.1 m, voxel 9 0.08 m.
  FrameVector frames({frameAt({0.05, 0.05, 0.05}, test::cloudOf({{0.93f, 0.0f, 0.0f}}))});
  const IntegrationStats st = integrate(frames, map, exactUncompressed());
  EXPECT_EQ(st.points, 1u);
  EXPECT_EQ(st.pointsSkipped(), 0u);
  auto key = [&](double x) { return *map.grid().keyOf({x, 0.05, 0.05}); };
  EXPECT_NEAR(map.find(key(0.05))->length_m, 0.05, 1e-6);
  for (int i = 1; i <= 8; ++i) {
    auto c = map.find(key(0.1 * i + 0.05));
    ASSERT_TRUE(c);
    EXPECT_NEAR(c->length_m, 0.1, 1e-6);
    EXPECT_EQ(c->hits, 0u);
    EXPECT_EQ(c->state(), VoxelState::Free);
  }
  auto end = map.find(key(0.95));
  ASSERT_TRUE(end);
  EXPECT_NEAR(end->length_m, 0.08, 1e-6);
  EXPECT_EQ(end->hits, 1u);
  EXPECT_EQ(end->state(), VoxelState::Occupied);
  EXPECT_EQ(map.stateOf(key(1.05)), VoxelState::Unknown);          // behind the hit
  EXPECT_EQ(map.stateOf(*map.grid().keyOf({0.5, 0.25, 0.05})), VoxelState::Unknown);  // beside the ray
  EXPECT_EQ(map.leafCount(), 10u);
}

TEST(Integrator, RecordsWhereInTheVoxelRaysEnd) {
  // Three points in the voxel [0.9, 1.0) x [0, 0.1) x [0, 0.1) (centre 0.95, 0.05, 0.05), one in
  // the next; the sensor at the centre of voxel 0. Offsets from the centre, in voxels.
  for (bool fast : {false, true}) {
    SessionMap map(0.1);
    IntegratorSettings s = exactUncompressed();
    s.fast = fast;
    const PointCloud cloud =
        test::cloudOf({{0.88f, 0.02f, -0.01f}, {0.91f, -0.03f, 0.0f}, {0.86f, 0.04f, 0.035f}, {0.955f, 0.0f, 0.0f}});
    integrate(FrameVector({frameAt({0.05, 0.05, 0.05}, cloud)}), map, s);
    const auto end = map.find(*map.grid().keyOf({0.95, 0.05, 0.05}));
    ASSERT_TRUE(end);
    ASSERT_EQ(end->hits, 3u);
    // x: 0.93, 0.96, 0.91 against 0.95; y: 0.07, 0.02, 0.09 against 0.05; z: 0.04, 0.05, 0.085.
    EXPECT_NEAR(end->offset[0], (-0.02 + 0.01 - 0.04) / 0.1, 1e-5) << "fast=" << fast;
    EXPECT_NEAR(end->offset[1], (0.02 - 0.03 + 0.04) / 0.1, 1e-5);
    EXPECT_NEAR(end->offset[2], (-0.01 + 0.0 + 0.035) / 0.1, 1e-5);
    EXPECT_NEAR(end->meanOffset(0), -0.05 / 0.3, 1e-5);
    const auto next = map.find(*map.grid().keyOf({1.05, 0.05, 0.05}));
    ASSERT_TRUE(next);
    EXPECT_NEAR(next->offset[0], -0.45, 1e-5) << "x = 1.005 lies 0.005 m past the voxel's lower face";
    // Voxels the rays only crossed hold no offsets.
    EXPECT_EQ(map.find(*map.grid().keyOf({0.55, 0.05, 0.05}))->offset[0], 0.0f);
  }
}

TEST(Integrator, DiagonalRayLengthsSumToItsLength) {
  SessionMap map(0.05);
  const Eigen::Vector3f p(0.4f, 0.3f, -0.5f);
  FrameVector frames({frameAt({0.01, 0.02, 0.03}, test::cloudOf({p}))});
  integrate(frames, map, exactUncompressed());
  double sum = 0.0;
  uint32_t hits = 0;
  map.forEachLeaf([&](const LeafView& l) {
    sum += l.counters.length_m;
    hits += l.counters.hits;
  });
  EXPECT_NEAR(sum, p.cast<double>().norm(), 1e-5);
  EXPECT_EQ(hits, 1u);
  EXPECT_EQ(map.find(*map.grid().keyOf(Eigen::Vector3d(0.01, 0.02, 0.03) + p.cast<double>())).value().hits, 1u);
}

TEST(Integrator, DiscardsPointsBeyondMaxRangeEntirely) {
  SessionMap map(0.1);
  IntegratorSettings s = exactUncompressed();
  s.max_range_m = 3.0;
  FrameVector frames({frameAt({0.05, 0.05, 0.05}, test::cloudOf({{2.9f, 0, 0}, {0, 3.1f, 0}}))});
  const IntegrationStats st = integrate(frames, map, s);
  EXPECT_EQ(st.points, 1u);
  EXPECT_EQ(st.points_out_of_range, 1u);
  // Nothing along the discarded ray is observed, not even as free space.
  EXPECT_EQ(map.stateOf(*map.grid().keyOf({0.05, 1.05, 0.05})), VoxelState::Unknown);
  EXPECT_EQ(map.stateOf(*map.grid().keyOf({1.05, 0.05, 0.05})), VoxelState::Free);
}

TEST(Integrator, CarvesFreeSpaceUpToTheRangeAlongRaysBeyondIt) {
  // From the centre of voxel 0 towards x = 5 m with a 3 m range: the ray is pulled back to
  // x = 3.05, so voxel 0 gets 0.05 m, voxels 1..29 0.1 m and voxel 30 0.05 m, none a hit; a point
  // within range is cast as before.
  for (bool fast : {false, true}) {
    SessionMap map(0.1);
    IntegratorSettings s = exactUncompressed();
    s.fast = fast;
    s.max_range_m = 3.0;
    s.carve_beyond_range = true;
    FrameVector frames({frameAt({0.05, 0.05, 0.05}, test::cloudOf({{5.0f, 0, 0}, {0, 0.93f, 0}}))});
    const IntegrationStats st = integrate(frames, map, s);
    EXPECT_EQ(st.points, 1u) << "fast=" << fast;
    EXPECT_EQ(st.points_out_of_range, 1u);
    auto at = [&](double x, double y) { return map.find(*map.grid().keyOf({x, y, 0.05})); };
    EXPECT_NEAR(at(0.05, 0.05)->length_m, 0.05 + 0.05, 1e-6);  // both rays start here
    for (int i = 1; i <= 29; ++i) {
      const auto c = at(0.1 * i + 0.05, 0.05);
      ASSERT_TRUE(c) << "voxel " << i;
      EXPECT_NEAR(c->length_m, 0.1, 1e-5) << "voxel " << i;
      EXPECT_EQ(c->hits, 0u);
      EXPECT_EQ(c->state(), VoxelState::Free);
    }
    EXPECT_NEAR(at(3.05, 0.05)->length_m, 0.05, 1e-5);
    EXPECT_EQ(at(3.05, 0.05)->hits, 0u);
    EXPECT_EQ(map.stateOf(*map.grid().keyOf({3.15, 0.05, 0.05})), VoxelState::Unknown);  // past the range
    EXPECT_EQ(at(0.05, 0.95)->hits, 1u);
    EXPECT_EQ(map.leafCount(), 31u + 9u);
  }
}

TEST(Integrator, CarvingBeyondTheRangeOnlyAddsTheLengthOfThePulledBackRays) {
  // Property, on random clouds around random poses: the map with carving holds every hit,
  // colour and offset of the map without, each voxel's length at least as long, and the total
  // length grows by the range once per point beyond it (exact mode: every ray's lengths sum to
  // its length). Nothing farther than the range (plus a voxel's diagonal) is touched.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(-6.0f, 6.0f);
  std::uniform_real_distribution<double> angle(-3.0, 3.0);
  for (int trial = 0; trial < 8; ++trial) {
    PointCloud cloud;
    for (int i = 0; i < 400; ++i) cloud.points.emplace_back(coord(rng), coord(rng), coord(rng));
    cloud.width = static_cast<uint32_t>(cloud.points.size());
    Frame f = frameAt({angle(rng), angle(rng), angle(rng)}, cloud);
    f.T_world_sensor.linear() = Eigen::AngleAxisd(angle(rng), Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
    const FrameVector frames({f});
    IntegratorSettings s = exactUncompressed();
    s.max_range_m = 4.0;
    SessionMap plain(0.1), carved(0.1);
    const IntegrationStats st = integrate(frames, plain, s);
    s.carve_beyond_range = true;
    integrate(frames, carved, s);
    double plain_sum = 0.0, carved_sum = 0.0;
    plain.forEachLeaf([&](const LeafView& l) {
      plain_sum += l.counters.length_m;
      const auto c = carved.find(l.key);
      ASSERT_TRUE(c);
      EXPECT_EQ(c->hits, l.counters.hits);
      EXPECT_EQ(c->red, l.counters.red);
      EXPECT_EQ(c->offset[0], l.counters.offset[0]);
      EXPECT_GE(c->length_m, l.counters.length_m - 1e-6f);
    });
    const double reach = s.max_range_m + std::sqrt(3.0) * 0.1;
    carved.forEachLeaf([&](const LeafView& l) {
      carved_sum += l.counters.length_m;
      EXPECT_LE((carved.grid().centerOf(l.key) - f.T_world_sensor.translation()).norm(), reach);
    });
    ASSERT_GT(st.points_out_of_range, 0u);
    EXPECT_NEAR(carved_sum - plain_sum, static_cast<double>(st.points_out_of_range) * s.max_range_m,
                1e-4 * carved_sum)
        << "trial " << trial;
  }
}

/// (key, level, hits, state) of every leaf: what two integrations must agree on.
std::vector<std::tuple<uint64_t, int, uint64_t, VoxelState>> leafSummary(const SessionMap& map) {
  std::vector<std::tuple<uint64_t, int, uint64_t, VoxelState>> out;
  map.forEachLeaf([&](const LeafView& leaf) {
    out.emplace_back(mortonEncode(leaf.key), leaf.level, leaf.counters.hits, map.stateOf(leaf.key));
  });
  return out;
}

TEST(Integrator, AnyRangeBeyondTheSceneGivesTheSameMap) {
  // Points at voxel centres 1 to 4 m from a sensor at a voxel centre, so that rounding cannot
  // move one across a voxel face: every range that reaches them all must give the same voxels,
  // however large (a range of 1e12 m used to leave no point at all, 1e6 m a fraction).
  PointCloud cloud;
  for (int i = 0; i < 300; ++i) {
    const double a = 0.37 * i, b = 0.11 * i;
    const double r = 10 + (i % 31);  // voxels
    const Eigen::Vector3d d(std::cos(a) * std::cos(b), std::sin(a) * std::cos(b), std::sin(b));
    const Eigen::Vector3d k = (d * r).array().round().matrix();
    cloud.points.push_back((k * 0.1).cast<float>());
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  const FrameVector frames({frameAt({0.05, 0.05, 0.05}, cloud)});
  for (bool fast : {false, true}) {
    IntegratorSettings s = exactUncompressed();
    s.fast = fast;
    s.max_range_m = 5.0;
    SessionMap reference(0.1);
    integrate(frames, reference, s);
    for (double range : {1e3, 1e6, 1e12, 1e30, std::numeric_limits<double>::max()}) {
      s.max_range_m = range;
      SessionMap map(0.1);
      const IntegrationStats st = integrate(frames, map, s);
      EXPECT_EQ(st.points, cloud.points.size()) << "fast=" << fast << " range=" << range;
      EXPECT_EQ(leafSummary(map), leafSummary(reference)) << "fast=" << fast << " range=" << range;
    }
  }
  // A point within a huge range but far outside the map is counted as outside, not cast.
  IntegratorSettings s = exactUncompressed();
  s.max_range_m = 1e30;
  SessionMap map(0.1);
  const IntegrationStats st =
      integrate(FrameVector({frameAt({0.05, 0.05, 0.05}, test::cloudOf({{1e18f, 0, 0}, {0, 3e9f, 0}, {1, 0, 0}}))}),
                map, s);
  EXPECT_EQ(st.points, 1u);
  EXPECT_EQ(st.points_outside_map, 2u);
}

// Points anywhere (not at voxel centres), seen from a rotated sensor off a voxel centre: a range
// that reaches them all gives the same map bit for bit, however far it reaches, in exact and
// fast mode. (The working frame's bias followed the range; the floats of a far bias rounded
// points differently: 24,986 occupied voxels at --max-range 1e6 against 25,017 at 6 m.)
TEST(Integrator, AnyRangeBeyondTheSceneGivesTheSameMapForAnyPoints) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Frame> frames;
  for (int f = 0; f < 3; ++f) {
    PointCloud cloud;
    for (int i = 0; i < 4000; ++i) {
      Eigen::Vector3f d(u(rng), u(rng), 1.0f + 0.5f * u(rng));
      cloud.points.push_back(d.normalized() * (0.5f + 1.25f * (u(rng) + 1.0f)));  // 0.5 to 3 m
    }
    cloud.width = static_cast<uint32_t>(cloud.points.size());
    Frame frame = frameAt({0.013 + 0.3 * f, -0.071, 0.029}, cloud);
    frame.T_world_sensor.linear() = Eigen::AngleAxisd(0.3 + f, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    frames.push_back(std::move(frame));
  }
  const FrameVector source(std::move(frames));
  for (bool fast : {false, true}) {
    IntegratorSettings s = exactUncompressed();
    s.fast = fast;
    s.max_range_m = 3.01;
    SessionMap reference(0.05);
    integrate(source, reference, s);
    ASSERT_GT(reference.counts().occupied_voxels, 1000u);
    for (double range : {3.5, 6.0, 1e3, 1e6, 1e30}) {
      s.max_range_m = range;
      SessionMap map(0.05);
      integrate(source, map, s);
      EXPECT_EQ(leafSummary(map), leafSummary(reference)) << "fast=" << fast << " range=" << range;
    }
  }
}

// Every voxel's hits, colour sums and offset sums are those of the points that end in it,
// counted here one by one (points near voxel centres, so that no rounding decides their voxel),
// in both modes and on every scratch path: the range cube, the box (a cube too large for its
// limit) and the list. More points than one bundling chunk (8,192), so later chunks are read
// from their offset in the cloud.
TEST(Integrator, EveryPathSumsEachVoxelsHitsAndColours) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> cell(-30, 30), byte(0, 255);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  const double res = 0.05;
  const Eigen::Vector3d origin(0.5 * res, 0.5 * res, 0.5 * res);
  PointCloud cloud;
  struct Sums {
    uint32_t hits = 0, red = 0, green = 0, blue = 0;
    double offset[3] = {0.0, 0.0, 0.0};  // voxels
  };
  std::map<std::tuple<int, int, int>, Sums> expected;
  for (int i = 0; i < 10000; ++i) {
    // Few cells for many points: most voxels get several, in runs and alternating.
    const int v[3] = {cell(rng) / 6, cell(rng) / 6, 8 + cell(rng) / 10};
    Eigen::Vector3d p;
    for (int a = 0; a < 3; ++a) p[a] = (v[a] + 0.5 + jitter(rng)) * res;
    const Rgb c{static_cast<uint8_t>(byte(rng)), static_cast<uint8_t>(byte(rng)), static_cast<uint8_t>(byte(rng))};
    cloud.points.push_back((p - origin).cast<float>());
    cloud.colours.push_back(c);
    Sums& e = expected[{v[0], v[1], v[2]}];
    ++e.hits;
    e.red += c.r;
    e.green += c.g;
    e.blue += c.b;
    for (int a = 0; a < 3; ++a) e.offset[a] += p[a] / res - (v[a] + 0.5);
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  const FrameVector frames({frameAt(origin, cloud)});
  for (const bool fast : {false, true}) {
    for (const int path : {0, 1, 2}) {  // fast mode's range cube, its box, the point list
      for (const double range : {3.0, 1e6}) {
        IntegratorSettings s = exactUncompressed();
        s.fast = fast;
        s.max_range_m = range;
        if (path >= 1) s.cube_max_cells = 8;
        if (path == 2) s.dense_grid_max_cells = 8;
        SessionMap map(res);
        integrate(frames, map, s);
        for (const auto& [v, e] : expected) {
          const auto key = map.grid().keyOf(Eigen::Vector3d((std::get<0>(v) + 0.5) * res, (std::get<1>(v) + 0.5) * res,
                                                            (std::get<2>(v) + 0.5) * res));
          ASSERT_TRUE(key);
          const std::optional<VoxelCounters> c = map.find(*key);
          ASSERT_TRUE(c);
          EXPECT_EQ(c->hits, e.hits) << "fast=" << fast << " path=" << path << " range=" << range;
          EXPECT_EQ(c->red, e.red);
          EXPECT_EQ(c->green, e.green);
          EXPECT_EQ(c->blue, e.blue);
          for (int a = 0; a < 3; ++a) EXPECT_NEAR(c->offset[a], e.offset[a], 1e-4 * e.hits);
        }
      }
    }
  }
}

// Fast mode's range cube goes back to a pool, zero, when an integration ends, and the next one
// takes it (integrate/zero_pages.h): maps made with a kept cube, after other frames used it and
// after a frame was refused half way, are the maps made with a new one, on one and two threads.
TEST(Integrator, FastModeMakesTheSameMapsWithAKeptCube) {
  auto randomFrames = [](uint32_t seed, double x0) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Frame> frames;
    for (int f = 0; f < 3; ++f) {
      PointCloud cloud;
      for (int i = 0; i < 3000; ++i) {
        const Eigen::Vector3f d(u(rng), u(rng), 1.0f + 0.5f * u(rng));
        cloud.points.push_back(d.normalized() * (0.5f + 1.2f * (u(rng) + 1.0f)));
        cloud.colours.push_back(Rgb{static_cast<uint8_t>(i % 251), 7, static_cast<uint8_t>(f)});
      }
      cloud.width = static_cast<uint32_t>(cloud.points.size());
      Frame frame = frameAt({x0 + 0.2 * f, -0.071, 0.029}, cloud);
      frame.T_world_sensor.linear() =
          Eigen::AngleAxisd(0.4 + f, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
      frames.push_back(std::move(frame));
    }
    return FrameVector(std::move(frames));
  };
  const FrameVector a = randomFrames(3, 0.013), b = randomFrames(4, -0.4);
  IntegratorSettings s = exactUncompressed();
  s.fast = true;
  s.max_range_m = 3.0;
  auto bytesOf = [&](const FrameVector& frames, int threads) {
    s.threads = threads;
    SessionMap map(0.05);
    integrate(frames, map, s);
    EXPECT_GT(map.counts().occupied_voxels, 500u);
    return encodeSessionMap(map, nlohmann::json::object());
  };
  integrate_detail::ZeroPool::clear();
  const std::vector<uint8_t> first = bytesOf(a, 1);
  // The cube and the box's lengths given back (and any smaller box a larger frame's replaced).
  EXPECT_GE(integrate_detail::ZeroPool::keptBlocks(), 2u);
  const std::vector<uint8_t> other = bytesOf(b, 1);
  EXPECT_NE(other, first);
  EXPECT_EQ(bytesOf(a, 1), first);
  EXPECT_EQ(bytesOf(a, 2), first);
  EXPECT_EQ(bytesOf(b, 2), other);
  // A frame refused after a good one: the next integration is still exact.
  std::vector<Frame> broken{a.load(0), a.load(1)};
  broken[1].T_world_sensor.translation() = Eigen::Vector3d(1e9, 0, 0);
  EXPECT_THROW(bytesOf(FrameVector(std::move(broken)), 1), DataError);
  EXPECT_EQ(bytesOf(a, 1), first);
  integrate_detail::ZeroPool::clear();
}

// A cube left with written cells (a frame that stopped between bundling and emission, which
// only running out of memory can do) is cleared before its next frame and never kept.
TEST(Integrator, ACubeLeftDirtyIsClearedAndNotKept) {
  integrate_detail::ZeroPool::clear();
  {
    integrate_detail::CubeStore cube;
    cube.ensure(5, 0);
    ASSERT_GE(cube.cells, 125u);
    cube.clean = false;
    for (size_t i = 0; i < cube.cells; i += 7) cube.end[i] = 3;
    cube.ensure(4, 0);  // room enough: the same block, cleared
    EXPECT_TRUE(cube.clean);
    EXPECT_EQ(std::count(cube.end, cube.end + cube.cells, 0u), static_cast<std::ptrdiff_t>(cube.cells));
    cube.clean = false;
    cube.end[1] = 9;
  }
  EXPECT_EQ(integrate_detail::ZeroPool::keptBlocks(), 0u);  // dirty: freed, not kept
  {
    integrate_detail::CubeStore cube;
    cube.ensure(5, 0);
  }
  EXPECT_EQ(integrate_detail::ZeroPool::keptBlocks(), 1u);  // clean: kept
  integrate_detail::ZeroPool::clear();
}

// The same for the bounding-box store: cleared before its next frame, never kept dirty.
TEST(Integrator, ABoxLeftDirtyIsClearedAndNotKept) {
  integrate_detail::ZeroPool::clear();
  const int64_t lo[3] = {0, 0, 0}, hi[3] = {4, 4, 4};
  {
    integrate_detail::DenseStore d;
    d.reset(lo, hi);
    ASSERT_GE(d.length_cells, 125u);
    ASSERT_GE(d.end_cells, 125u);
    for (size_t i = 0; i < 125; i += 7) {
      d.length[i] = 1.5f;
      d.end[i] = 3;
    }
    const int64_t hi2[3] = {3, 4, 2};
    d.reset(lo, hi2);  // room enough: the same blocks, cleared (the earlier frame never read)
    EXPECT_EQ(std::count(d.length, d.length + d.length_cells, 0.0f), static_cast<std::ptrdiff_t>(d.length_cells));
    EXPECT_EQ(std::count(d.end, d.end + d.end_cells, 0u), static_cast<std::ptrdiff_t>(d.end_cells));
    d.length[1] = 2.0f;
    d.end[2] = 5;
    // Grown while dirty (past a block rounded up to 2 MiB): cleared first, then given back.
    const int64_t larger[3] = {100, 100, 100};
    d.reset(lo, larger);
    EXPECT_EQ(integrate_detail::ZeroPool::keptBlocks(), 2u);
    while (integrate_detail::ZeroPool::keptBlocks() > 0) {
      const integrate_detail::ZeroPages block = integrate_detail::ZeroPool::take(1);
      const auto* bytes = static_cast<const unsigned char*>(block.data());
      EXPECT_EQ(std::count(bytes, bytes + block.bytes(), 0), static_cast<std::ptrdiff_t>(block.bytes()));
    }
    d.length[3] = 1.0f;
  }
  EXPECT_EQ(integrate_detail::ZeroPool::keptBlocks(), 0u);  // dirty: freed, not kept
  {
    integrate_detail::DenseStore d;
    d.reset(lo, hi);
    d.rest();
  }
  EXPECT_EQ(integrate_detail::ZeroPool::keptBlocks(), 2u);  // clean: both kept
  integrate_detail::ZeroPool::clear();
}

// Every path that writes the scratch stores (the range cube, the bounding box in fast and in
// exact mode, the rays carved beyond the range) leaves them zero: the blocks kept for the next
// integration are zero, and an integration after others gives the bytes of one in a fresh
// process, on one thread and on two.
TEST(Integrator, EveryPathLeavesItsStoresZero) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  auto randomFrames = [&](double x0, float reach) {
    std::vector<Frame> frames;
    for (int f = 0; f < 3; ++f) {
      PointCloud cloud;
      for (int i = 0; i < 2000; ++i) {
        const Eigen::Vector3f d(u(rng), u(rng), 1.0f + 0.5f * u(rng));
        cloud.points.push_back(d.normalized() * (0.3f + reach * 0.5f * (u(rng) + 1.0f)));
        cloud.colours.push_back(Rgb{static_cast<uint8_t>(i % 251), 9, static_cast<uint8_t>(f)});
      }
      cloud.width = static_cast<uint32_t>(cloud.points.size());
      Frame frame = frameAt({x0 + 0.15 * f, 0.031, -0.047}, cloud);
      frame.T_world_sensor.linear() =
          Eigen::AngleAxisd(0.3 + f, Eigen::Vector3d(3, 1, 2).normalized()).toRotationMatrix();
      frames.push_back(std::move(frame));
    }
    return FrameVector(std::move(frames));
  };
  // Near the map's edge (x = 1,309.5 m of its 1,310.72 m at 0.04 m, points up to 2.3 m away) the
  // range cube does not lie inside the map: fast mode takes the point list.
  const FrameVector a = randomFrames(0.02, 2.0f), b = randomFrames(-0.7, 3.0f), edge = randomFrames(1309.5, 2.0f);
  struct Path {
    const char* name;
    IntegratorSettings settings;
    const FrameVector* frames;
  };
  std::vector<Path> paths;
  IntegratorSettings s = exactUncompressed();
  s.max_range_m = 3.5;
  paths.push_back({"exact, the points' box", s, &a});
  s.fast = true;
  paths.push_back({"fast, the range cube", s, &a});
  paths.push_back({"fast, the point list (the map's edge)", s, &edge});
  s.carve_level = 2;
  paths.push_back({"fast, the range cube, carved two levels coarser", s, &a});
  s.cube_max_cells = 1;
  paths.push_back({"fast, the box, carved two levels coarser", s, &a});
  s.carve_level = 0;
  paths.push_back({"fast, the box", s, &a});
  s.max_range_m = 1.2;  // most points beyond: their rays carved to the range
  s.carve_beyond_range = true;
  paths.push_back({"fast, the box, carved beyond the range", s, &a});
  s.cube_max_cells = IntegratorSettings{}.cube_max_cells;
  paths.push_back({"fast, the cube, carved beyond the range", s, &a});
  for (const Path& p : paths) {
    IntegratorSettings settings = p.settings;
    auto bytesOf = [&](const FrameVector& frames, int threads) {
      settings.threads = threads;
      SessionMap map(0.04);
      integrate(frames, map, settings);
      EXPECT_GT(map.counts().occupied_voxels, 300u) << p.name;
      return encodeSessionMap(map, nlohmann::json::object());
    };
    // Each frame cast by a new accumulator from an empty pool: nothing a frame left behind can
    // reach the next.
    auto alone = [&](const FrameVector& frames) {
      SessionMap map(0.04);
      for (size_t i = 0; i < frames.size(); ++i) {
        integrate_detail::ZeroPool::clear();
        RayAccumulator acc(map.grid(), integrate_detail::perThread(settings, 1));
        VoxelDeltas deltas;
        acc.accumulate(frames.load(i), deltas);
        mergeDeltas(map, deltas);
      }
      if (settings.compress_free) map.compressFree();
      return encodeSessionMap(map, nlohmann::json::object());
    };
    const FrameVector& mine = *p.frames;
    if (&mine == &edge) {  // the path taken: points beyond the map's edge are counted
      SessionMap probe(0.04);
      EXPECT_GT(integrate(mine, probe, settings).points_outside_map, 0u);
    }
    integrate_detail::ZeroPool::clear();
    const std::vector<uint8_t> first = bytesOf(mine, 1), other = bytesOf(b, 1);
    EXPECT_EQ(first, alone(mine)) << p.name;
    EXPECT_NE(other, first) << p.name;
    integrate_detail::ZeroPool::clear();
    bytesOf(mine, 1);
    bytesOf(b, 1);
    EXPECT_GT(integrate_detail::ZeroPool::keptBlocks(), 0u) << p.name;
    EXPECT_EQ(bytesOf(mine, 1), first) << p.name;
    EXPECT_EQ(bytesOf(mine, 2), first) << p.name;
    EXPECT_EQ(bytesOf(b, 2), other) << p.name;
    // Every kept block reads zero.
    while (integrate_detail::ZeroPool::keptBlocks() > 0) {
      const integrate_detail::ZeroPages block = integrate_detail::ZeroPool::take(1);
      const auto* bytes = static_cast<const unsigned char*>(block.data());
      EXPECT_EQ(std::count(bytes, bytes + block.bytes(), 0), static_cast<std::ptrdiff_t>(block.bytes())) << p.name;
    }
  }
  integrate_detail::ZeroPool::clear();
}

TEST(Integrator, ResolutionsOutsideTheLimitsAreRefused) {
  EXPECT_NO_THROW(KeyGrid{kMinResolution_m});
  EXPECT_NO_THROW(KeyGrid{kMaxResolution_m});
  for (double r : {0.0, -0.05, kMinResolution_m / 2, kMaxResolution_m * 2, 1e300, std::nan("")}) {
    EXPECT_THROW(KeyGrid{r}, UsageError) << r;
  }
}

TEST(Integrator, SkipsAndCountsInvalidPoints) {
  SessionMap map(0.1);
  const float nan = std::nanf(""), inf = std::numeric_limits<float>::infinity();
  FrameVector frames({frameAt({0.05, 0.05, 0.05}, test::cloudOf({{nan, 0, 0}, {inf, 0, 0}, {0, 0, 0}, {0.5f, 0, 0}}))});
  const IntegrationStats st = integrate(frames, map, exactUncompressed());
  EXPECT_EQ(st.points, 1u);
  EXPECT_EQ(st.points_invalid, 3u);
}

TEST(Integrator, CountsPointsOutsideTheMap) {
  SessionMap map(0.001);  // extent +-32.768 m
  IntegratorSettings s = exactUncompressed();
  s.max_range_m = 100.0;
  FrameVector frames({frameAt({32.7, 0, 0}, test::cloudOf({{1.0f, 0, 0}, {-1.0f, 0, 0}}))});
  const IntegrationStats st = integrate(frames, map, s);
  EXPECT_EQ(st.points, 1u);
  EXPECT_EQ(st.points_outside_map, 1u);
}

TEST(Integrator, RejectsBadPosesAndSettings) {
  SessionMap map(0.1);
  Frame f = frameAt({0, 0, 0}, test::cloudOf({{1, 0, 0}}));
  f.T_world_sensor.translation().x() = std::nan("");
  EXPECT_THROW(integrate(FrameVector({f}), map, exactUncompressed()), DataError);
  f.T_world_sensor.translation().x() = 1e6;  // outside the map
  EXPECT_THROW(integrate(FrameVector({f}), map, exactUncompressed()), DataError);
  IntegratorSettings s;
  s.max_range_m = -1;
  EXPECT_THROW(integrate(FrameVector({}), map, s), UsageError);
}

TEST(Integrator, StopsWhenTheMapPassesTheMemoryLimit) {
  const PinholeCamera cam = smallCamera(160);
  const FrameVector frames(benchmarkSequence(4, cam));
  IntegratorSettings s = exactUncompressed();
  SessionMap unlimited(0.02);
  s.memory_limit_bytes = 0;
  integrate(frames, unlimited, s);
  // A limit below what the map needs: stopped after a frame with the map's size and resolution.
  for (int threads : {1, 2}) {
    s.threads = threads;
    s.memory_limit_bytes = unlimited.memoryBytes() / 2;
    SessionMap map(0.02);
    try {
      integrate(frames, map, s);
      ADD_FAILURE() << "integrated past the memory limit";
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("the session map"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("at resolution 0.02 m"), std::string::npos) << e.what();
    }
    EXPECT_LE(map.reservedBytes(), 2 * unlimited.reservedBytes());
  }
  // A limit above it changes nothing.
  s.memory_limit_bytes = 4 * unlimited.reservedBytes() + (size_t{64} << 20);
  SessionMap limited(0.02);
  integrate(frames, limited, s);
  EXPECT_EQ(limited.memoryBytes(), unlimited.memoryBytes());
  EXPECT_GT(defaultMemoryLimitBytes(), size_t{0});
}

TEST(Integrator, FastModeKeepsHitsAndColoursAndBoundsLengths) {
  const PinholeCamera cam = smallCamera(160);
  auto frames = benchmarkSequence(4, cam);
  for (auto& f : frames) f.cloud.colours.assign(f.cloud.size(), Rgb{10, 20, 30});
  const double res = 0.05;
  SessionMap exact(res), fast(res);
  IntegratorSettings s = exactUncompressed();
  const IntegrationStats se = integrate(FrameVector(frames), exact, s);
  s.fast = true;
  const IntegrationStats sf = integrate(FrameVector(frames), fast, s);
  EXPECT_EQ(se.points, sf.points);
  EXPECT_LT(sf.rays, se.rays);

  std::map<VoxelKey, VoxelCounters> a, b;
  exact.forEachLeaf([&](const LeafView& l) { a[l.key] = l.counters; });
  fast.forEachLeaf([&](const LeafView& l) { b[l.key] = l.counters; });
  double len_a = 0, len_b = 0;
  size_t both = 0, agree = 0;
  for (auto& [k, c] : a) {
    len_a += c.length_m;
    auto it = b.find(k);
    const uint32_t hits_b = it == b.end() ? 0 : it->second.hits;
    EXPECT_EQ(c.hits, hits_b);  // bound 1: every voxel has the same hits, colour and position sums
    if (it != b.end()) {
      EXPECT_EQ(c.red, it->second.red);
      for (int axis = 0; axis < 3; ++axis) EXPECT_NEAR(c.offset[axis], it->second.offset[axis], 1e-3);
      ++both;
      agree += c.state() == it->second.state();
    }
  }
  for (auto& [k, c] : b) {
    len_b += c.length_m;
    if (!a.count(k)) {
      EXPECT_EQ(c.hits, 0u);
    }
  }
  // Bound 2: the summed ray length differs by at most half a voxel diagonal per point (each
  // bundle ray ends at its voxel's centre, within sqrt(3)/2 voxel edges of each of its points).
  EXPECT_LE(std::abs(len_a - len_b), static_cast<double>(se.points) * std::sqrt(3.0) / 2.0 * res);
  // Measured: the states of voxels known in both modes agree almost everywhere.
  EXPECT_GT(static_cast<double>(agree) / static_cast<double>(both), 0.97);
}

TEST(Integrator, ResultsDoNotDependOnThreadCount) {
  const PinholeCamera cam = smallCamera(200);
  const FrameVector frames(benchmarkSequence(12, cam));
  for (bool fast : {false, true}) {
    std::vector<uint8_t> reference;
    for (int threads : {1, 2, 4}) {
      SessionMap map(0.05);
      IntegratorSettings s;
      s.fast = fast;
      s.threads = threads;
      integrate(frames, map, s);
      CmapHeader h;
      h.resolution_m = map.resolution_m();
      std::vector<CmapBlock> blocks(2);
      blocks[0].tag = "INNR";
      blocks[0].data.assign(reinterpret_cast<const uint8_t*>(map.innerPool().data()),
                            reinterpret_cast<const uint8_t*>(map.innerPool().data() + map.innerPool().size()));
      // Every leaf behind its reference, in the order of the references (the pools' layout).
      blocks[1].tag = "LEAF";
      for (const SessionMap::Children& c : map.innerPool()) {
        for (const SessionMap::Ref r : c) {
          if (r == SessionMap::kEmpty || (r & SessionMap::kLeafBit) == 0) continue;
          const VoxelCounters v = map.leaf(r);
          blocks[1].data.insert(blocks[1].data.end(), reinterpret_cast<const uint8_t*>(&v),
                                reinterpret_cast<const uint8_t*>(&v + 1));
        }
      }
      const auto bytes = encodeCmap(h, blocks, 0);
      if (threads == 1) {
        reference = bytes;
      } else {
        EXPECT_EQ(bytes, reference) << "fast=" << fast << " threads=" << threads;
      }
    }
  }
}

TEST(Integrator, FrameByFrameGivesTheMapOfAllFramesAtOnce) {
  const PinholeCamera cam = smallCamera(200);
  const FrameVector frames(benchmarkSequence(12, cam));
  for (bool fast : {false, true}) {
    IntegratorSettings s;
    s.fast = fast;
    SessionMap all(0.05);
    const IntegrationStats stats = integrate(frames, all, s);
    IncrementalIntegrator incremental(0.05, s);
    for (const Frame& f : frames.frames()) incremental.add(f);
    EXPECT_EQ(incremental.stats().points, stats.points);
    EXPECT_EQ(incremental.stats().frames, frames.size());
    const SessionMap one_by_one = incremental.finish();
    EXPECT_TRUE(one_by_one == all) << "fast=" << fast;
    EXPECT_EQ(encodeSessionMap(one_by_one, {}), encodeSessionMap(all, {})) << "fast=" << fast;
    EXPECT_TRUE(incremental.map().empty());
    EXPECT_EQ(incremental.stats().frames, 0u);
  }
}

TEST(Integrator, EveryScratchPathGivesTheSameMap) {
  const PinholeCamera cam = smallCamera(120);
  const FrameVector frames(benchmarkSequence(3, cam));
  for (auto [fast, carve] : {std::pair{false, false}, std::pair{true, false}, std::pair{false, true}, std::pair{true, true}}) {
    IntegratorSettings s;
    s.fast = fast;
    s.threads = 1;
    // Carving beyond the range: a range shorter than the room, so that many points lie past it.
    s.carve_beyond_range = carve;
    if (carve) s.max_range_m = 1.5;
    SessionMap cube(0.05), dense(0.05), hashed(0.05);
    integrate(frames, cube, s);  // fast mode: one pass over the range cube
    s.cube_max_cells = 0;        // two passes over the bounding box (fast mode: the vectorised ones)
    integrate(frames, dense, s);
    s.dense_grid_max_cells = 0;  // hash table, from the point list
    integrate(frames, hashed, s);
    EXPECT_TRUE(cube == dense) << "fast=" << fast;
    EXPECT_TRUE(dense == hashed) << "fast=" << fast;
    // Fast mode's bundle rays: the portable lanes give the map of the vector lanes.
    SessionMap portable(0.05);
    s.cube_max_cells = IntegratorSettings{}.cube_max_cells;
    s.dense_grid_max_cells = IntegratorSettings{}.dense_grid_max_cells;
    s.simd = false;
    integrate(frames, portable, s);
    EXPECT_TRUE(portable == cube) << "fast=" << fast;
  }
}

TEST(Integrator, CompressionKeepsEveryVoxelState) {
  const PinholeCamera cam = smallCamera(160);
  const FrameVector frames(benchmarkSequence(3, cam));
  SessionMap plain(0.05), compressed(0.05);
  IntegratorSettings s = exactUncompressed();
  integrate(frames, plain, s);
  s.compress_free = true;
  integrate(frames, compressed, s);
  EXPECT_LT(compressed.leafCount(), plain.leafCount());
  size_t checked = 0;
  plain.forEachLeaf([&](const LeafView& l) {
    ASSERT_EQ(compressed.stateOf(l.key), l.counters.state());
    ++checked;
  });
  EXPECT_EQ(plain.counts().free_voxels, compressed.counts().free_voxels);
  EXPECT_EQ(plain.counts().occupied_voxels, compressed.counts().occupied_voxels);
  EXPECT_GT(checked, 1000u);
}

TEST(Integrator, CoarseCarvingKeepsHitsAndTheSummedLengthAndMostStates) {
  const PinholeCamera cam = smallCamera(160);
  auto frames = benchmarkSequence(3, cam);
  for (auto& f : frames) f.cloud.colours.assign(f.cloud.size(), Rgb{10, 20, 30});
  const double res = 0.02;
  SessionMap exact(res), fast(res), carved(res);
  IntegratorSettings s = exactUncompressed();
  integrate(FrameVector(frames), exact, s);
  s.fast = true;
  s.carve_level = 0;  // at 0.02 m the default (auto) would carve at level 2
  integrate(FrameVector(frames), fast, s);
  s.carve_level = 2;
  const IntegrationStats sc = integrate(FrameVector(frames), carved, s);
  // Hits, colours and hit positions are fast mode's, bit for bit: only lengths move.
  size_t hit_voxels = 0;
  double len_fast = 0, len_carved = 0;
  fast.forEachLeaf([&](const LeafView& l) {
    len_fast += l.counters.length_m;
    if (l.counters.hits == 0) return;
    ++hit_voxels;
    const auto c = carved.find(l.key);
    ASSERT_TRUE(c);
    EXPECT_EQ(c->hits, l.counters.hits);
    EXPECT_EQ(c->red, l.counters.red);
    for (int a = 0; a < 3; ++a) EXPECT_EQ(c->offset[a], l.counters.offset[a]);
  });
  size_t coarse_leaves = 0, carved_hit_voxels = 0;
  carved.forEachLeaf([&](const LeafView& l) {
    len_carved += l.counters.length_m;
    coarse_leaves += l.level > 0;
    carved_hit_voxels += l.counters.hits > 0;
  });
  EXPECT_EQ(carved_hit_voxels, hit_voxels);
  EXPECT_GT(coarse_leaves, 0u);
  // The summed length is fast mode's up to float rounding (each ray's parts sum to the ray).
  EXPECT_NEAR(len_carved, len_fast, 1e-4 * len_fast);
  // States against exact mode, over the voxels known in both (measured: docs/integration.md).
  size_t both = 0, agree = 0, occupied = 0, occupied_kept = 0, both_fast = 0, agree_fast = 0;
  exact.forEachLeaf([&](const LeafView& l) {
    const VoxelState want = l.counters.state();
    const VoxelState got = carved.stateOf(l.key);
    const VoxelState got_fast = fast.stateOf(l.key);
    if (got_fast != VoxelState::Unknown) {
      ++both_fast;
      agree_fast += got_fast == want;
    }
    if (want == VoxelState::Occupied) {
      ++occupied;
      occupied_kept += got == VoxelState::Occupied;
    }
    if (got == VoxelState::Unknown) return;
    ++both;
    agree += got == want;
  });
  const double agreement = static_cast<double>(agree) / static_cast<double>(both);
  const double kept = static_cast<double>(occupied_kept) / static_cast<double>(occupied);
  const uint64_t known_exact = exact.counts().free_voxels + exact.counts().occupied_voxels;
  const uint64_t known_carved = carved.counts().free_voxels + carved.counts().occupied_voxels;
  const uint64_t known_fast = fast.counts().free_voxels + fast.counts().occupied_voxels;
  std::printf("coarse carving, level 2 at 0.02 m: %zu voxels known in both, states agree %.6f (fast %.6f), "
              "occupied kept %.6f of %zu, known %llu (exact %llu, fast %llu), %llu cubes+voxels merged\n",
              both, agreement, static_cast<double>(agree_fast) / static_cast<double>(both_fast), kept, occupied,
              static_cast<unsigned long long>(known_carved), static_cast<unsigned long long>(known_exact),
              static_cast<unsigned long long>(known_fast),
              static_cast<unsigned long long>(sc.voxel_updates));
  // Measured 1.000000 and 1.000000 (hits decide occupancy, and they are fast mode's), with 13%
  // more voxels known: those of coarse cubes that no ray crossed, known free here, unknown in
  // exact mode (docs/integration.md).
  EXPECT_GT(agreement, 0.999);
  EXPECT_GT(kept, 0.999);
  EXPECT_LT(static_cast<double>(known_carved), 1.25 * static_cast<double>(known_exact));
}

TEST(Integrator, CoarseCarvingGivesTheSameMapOnEveryPathAndThreadCount) {
  const PinholeCamera cam = smallCamera(120);
  const FrameVector frames(benchmarkSequence(3, cam));
  IntegratorSettings s;
  s.fast = true;
  s.threads = 1;
  s.carve_level = 2;
  SessionMap cube(0.05), dense(0.05), hashed(0.05), portable(0.05), threads(0.05), plain(0.05);
  integrate(frames, cube, s);
  s.cube_max_cells = 0;  // two passes over the bounding box
  integrate(frames, dense, s);
  s.dense_grid_max_cells = 0;  // hash tables, for the voxels and for the coarse cells
  integrate(frames, hashed, s);
  s = IntegratorSettings{};
  s.fast = true;
  s.carve_level = 2;
  s.simd = false;
  s.threads = 1;
  integrate(frames, portable, s);
  s.simd = true;
  s.threads = 2;
  integrate(frames, threads, s);
  EXPECT_TRUE(cube == dense);
  EXPECT_TRUE(dense == hashed);
  EXPECT_TRUE(portable == cube);
  EXPECT_TRUE(threads == cube);
  IncrementalIntegrator one_by_one(0.05, s);
  for (const Frame& f : frames.frames()) one_by_one.add(f);
  EXPECT_TRUE(one_by_one.finish() == cube);
  s.carve_level = 0;
  integrate(frames, plain, s);
  EXPECT_FALSE(plain == cube);

  // At 0.02 m the bounding-box path is the default one: the hash tables (which hold every cell
  // a ray touched, even with length 0, as at a corner: not updates) and frame-by-frame
  // integration give its map.
  s = IntegratorSettings{};
  s.fast = true;
  s.threads = 1;
  s.carve_level = 2;
  SessionMap box(0.02), hashed_fine(0.02);
  integrate(frames, box, s);
  s.dense_grid_max_cells = 0;
  integrate(frames, hashed_fine, s);
  EXPECT_TRUE(box == hashed_fine);
  s.dense_grid_max_cells = IntegratorSettings{}.dense_grid_max_cells;
  IncrementalIntegrator one_at_a_time(0.02, s);
  for (const Frame& f : frames.frames()) one_at_a_time.add(f);
  EXPECT_TRUE(one_at_a_time.finish() == box);
}

TEST(Integrator, CoarseCarvingNeedsFastModeAndALevelUpToFour) {
  const FrameVector frames(benchmarkSequence(1, smallCamera(64)));
  SessionMap map(0.05);
  IntegratorSettings s;
  s.carve_level = 2;
  EXPECT_THROW(integrate(frames, map, s), UsageError);
  s.fast = true;
  s.carve_level = kMaxCarveLevel + 1;
  EXPECT_THROW(integrate(frames, map, s), UsageError);
  s.carve_level = kCarveAuto - 1;
  EXPECT_THROW(integrate(frames, map, s), UsageError);
  s.carve_level = kCarveAuto;  // fine in either mode
  EXPECT_NO_THROW(integrate(frames, map, s));
  s.fast = false;
  EXPECT_NO_THROW(integrate(frames, map, s));
}

// The default level (kCarveAuto) is 2 in fast mode at 0.025 m and finer, 0 otherwise; it gives
// the maps of that level set by hand.
TEST(Integrator, CoarseCarvingPicksItsLevelFromTheResolution) {
  IntegratorSettings s;
  EXPECT_EQ(s.carve_level, kCarveAuto);
  EXPECT_EQ(carveLevelFor(s, 0.02), 0);  // exact mode
  s.fast = true;
  EXPECT_EQ(carveLevelFor(s, 0.01), 2);
  EXPECT_EQ(carveLevelFor(s, 0.02), 2);
  EXPECT_EQ(carveLevelFor(s, 0.025), 2);
  EXPECT_EQ(carveLevelFor(s, 0.026), 0);
  EXPECT_EQ(carveLevelFor(s, 0.05), 0);
  s.carve_level = 1;
  EXPECT_EQ(carveLevelFor(s, 0.05), 1);
  s.carve_level = 0;
  EXPECT_EQ(carveLevelFor(s, 0.02), 0);

  const FrameVector frames(benchmarkSequence(2, smallCamera(96)));
  s.threads = 1;
  for (const double res : {0.02, 0.05}) {
    SessionMap automatic(res), by_hand(res), off(res);
    s.carve_level = kCarveAuto;
    integrate(frames, automatic, s);
    s.carve_level = res < 0.03 ? 2 : 0;
    integrate(frames, by_hand, s);
    s.carve_level = 0;
    integrate(frames, off, s);
    EXPECT_TRUE(automatic == by_hand) << res;
    EXPECT_EQ(automatic == off, res > 0.03) << res;
  }
}

/// FrameSharing within one process, for the tests: the "other process" is an accumulator of its
/// own that casts a handed-out frame when it is collected, its deltas passed through their bytes
/// (encodeDeltas) as between processes. Room for handed-out frames and whether an answer has
/// arrived are drawn at random.
class LocalSharing : public FrameSharing {
 public:
  /// `before`: frames 0 to before - 1 are handed out before integrate() begins (as mpirun's rank 0
  /// hands out the next recording's first frames), whatever the room.
  LocalSharing(const FrameSource& source, double resolution_m, const IntegratorSettings& settings, uint32_t seed,
               size_t room, size_t before = 0)
      : source_(source), accumulator_(KeyGrid(resolution_m), settings), random_(seed), room_(room) {
    for (size_t i = 0; i < std::min(before, source.size()); ++i) handed_.insert(i);
    handed_out = handed_.size();
  }
  void framesDone() override {
    EXPECT_TRUE(handed_.empty()) << "frames left handed out";
    ++frames_done;
  }
  size_t frames_done = 0;

  size_t handOut(size_t first, size_t end) override {
    size_t given = 0;
    while (first + given < end && handed_.size() < room_ && coin()) handed_.insert(first + given++);
    handed_out += given;
    return given;
  }
  bool handedOut(size_t i) const override { return handed_.count(i) != 0; }
  bool collect(size_t i, VoxelDeltas& out, bool wait) override {
    EXPECT_FALSE(handed_.empty());
    EXPECT_EQ(i, *handed_.begin()) << "collected out of frame order";
    if (!wait && coin()) return false;
    handed_.erase(i);
    VoxelDeltas cast;
    accumulator_.accumulate(source_.load(i), cast);  // what it throws is the answer
    decodeDeltas(encodeDeltas(cast), out, "frame " + std::to_string(i));
    return true;
  }
  size_t handed_out = 0;

 private:
  bool coin() { return std::uniform_int_distribution<int>(0, 1)(random_) == 1; }
  const FrameSource& source_;
  RayAccumulator accumulator_;
  std::mt19937 random_;
  size_t room_;
  std::set<size_t> handed_;
};

/// Frames of which some cannot be read (load throws a DataError naming the frame).
class FramesWithBadOnes : public FrameSource {
 public:
  FramesWithBadOnes(const FrameVector& frames, std::set<size_t> bad) : frames_(frames), bad_(std::move(bad)) {}
  size_t size() const override { return frames_.size(); }
  Frame load(size_t i) const override {
    if (bad_.count(i)) throw DataError("frame " + std::to_string(i) + " is unreadable");
    return frames_.load(i);
  }

 private:
  const FrameVector& frames_;
  std::set<size_t> bad_;
};

// Frames cast elsewhere (mpirun's ranks) and merged in frame order give the bytes of one process,
// whichever frames were handed out and whenever their answers arrived.
TEST(FrameSharing, SharedFramesGiveTheMapOfOneProcess) {
  const PinholeCamera cam = smallCamera(120);
  const FrameVector frames(benchmarkSequence(9, cam));
  struct Case {
    bool fast;
    int carve_level;
  };
  for (const Case c : {Case{false, 0}, Case{true, 0}, Case{true, 2}}) {
    IntegratorSettings s;
    s.fast = c.fast;
    s.carve_level = c.carve_level;
    s.threads = 1;
    SessionMap alone(0.05);
    const IntegrationStats expected = integrate(frames, alone, s);
    const std::vector<uint8_t> bytes = encodeSessionMap(alone, {});
    size_t shared_somewhere = 0;
    for (uint32_t seed = 0; seed < 12; ++seed) {
      LocalSharing sharing(frames, 0.05, s, seed, seed % 5, seed % 3 == 0 ? seed / 3 : 0);
      SessionMap map(0.05);
      size_t progress_calls = 0;
      const IntegrationStats stats = integrate(
          frames, map, s,
          [&](size_t done, size_t total) {
            EXPECT_EQ(done, ++progress_calls);
            EXPECT_EQ(total, frames.size());
          },
          &sharing);
      EXPECT_EQ(encodeSessionMap(map, {}), bytes) << "fast " << c.fast << " carve " << c.carve_level << " seed " << seed;
      EXPECT_EQ(stats.points, expected.points);
      EXPECT_EQ(stats.frames, expected.frames);
      EXPECT_EQ(stats.rays, expected.rays);
      EXPECT_EQ(stats.voxel_updates, expected.voxel_updates);
      EXPECT_EQ(progress_calls, frames.size());
      EXPECT_EQ(sharing.frames_done, 1u);
      EXPECT_LE(sharing.handed_out, frames.size());
      if (sharing.handed_out > 0 && sharing.handed_out < frames.size()) ++shared_somewhere;
    }
    EXPECT_GE(shared_somewhere, 6u) << "most seeds cast frames in both places";
  }
}

// A frame that cannot be read stops the integration with the error one process gives, the first
// bad frame in frame order's, whether it was handed out or cast here (even ahead of its turn).
TEST(FrameSharing, TheFirstBadFrameInFrameOrderStopsIt) {
  const PinholeCamera cam = smallCamera(80);
  const FrameVector frames(benchmarkSequence(10, cam));
  IntegratorSettings s;
  s.threads = 1;
  std::mt19937 random(5);
  for (int trial = 0; trial < 40; ++trial) {
    std::set<size_t> bad;
    const int count = std::uniform_int_distribution<int>(1, 3)(random);
    for (int k = 0; k < count; ++k) bad.insert(std::uniform_int_distribution<size_t>(0, frames.size() - 1)(random));
    const FramesWithBadOnes source(frames, bad);
    SessionMap alone(0.05);
    std::string expected;
    try {
      integrate(source, alone, s);
    } catch (const DataError& e) {
      expected = e.what();
    }
    ASSERT_EQ(expected, "frame " + std::to_string(*bad.begin()) + " is unreadable");
    LocalSharing sharing(source, 0.05, s, static_cast<uint32_t>(trial), 1 + trial % 4);
    SessionMap map(0.05);
    size_t merged = 0;
    try {
      integrate(source, map, s, [&](size_t done, size_t) { merged = done; }, &sharing);
      ADD_FAILURE() << "no error, trial " << trial;
    } catch (const DataError& e) {
      EXPECT_EQ(std::string(e.what()), expected) << "trial " << trial;
    }
    EXPECT_EQ(merged, *bad.begin()) << "the frames before the bad one were merged, trial " << trial;
  }
}

// A frame's deltas travel as bytes (mpirun's ranks): read back bit for bit; bytes cut short, with
// a byte too many, or of something else are refused with a FormatError.
TEST(FrameSharing, DeltasReadBackExactlyAndRefuseOtherBytes) {
  const PinholeCamera cam = smallCamera(120);
  const FrameVector frames(benchmarkSequence(2, cam));
  IntegratorSettings s;
  s.fast = true;
  s.carve_level = 2;
  RayAccumulator acc(KeyGrid(0.05), s);
  VoxelDeltas d;
  acc.accumulate(frames.load(1), d);
  ASSERT_FALSE(d.keys.empty());
  ASSERT_FALSE(d.cube_keys.empty());
  const std::vector<uint8_t> bytes = encodeDeltas(d);
  VoxelDeltas back;
  back.keys.resize(3);  // what was there before is replaced
  decodeDeltas(bytes, back, "test");
  EXPECT_EQ(back.keys, d.keys);
  ASSERT_EQ(back.deltas.size(), d.deltas.size());
  EXPECT_EQ(std::memcmp(back.deltas.data(), d.deltas.data(), d.deltas.size() * sizeof(VoxelCounters)), 0);
  EXPECT_EQ(back.cube_keys, d.cube_keys);
  EXPECT_EQ(back.cube_length_m, d.cube_length_m);
  EXPECT_EQ(back.cube_level, d.cube_level);
  EXPECT_EQ(back.stats.points, d.stats.points);
  EXPECT_EQ(back.stats.rays, d.stats.rays);
  EXPECT_EQ(back.stats.voxel_updates, d.stats.voxel_updates);
  EXPECT_EQ(encodeDeltas(back), bytes);
  std::mt19937 random(2);
  for (int k = 0; k < 50; ++k) {
    const size_t cut = std::uniform_int_distribution<size_t>(0, bytes.size() - 1)(random);
    EXPECT_THROW(decodeDeltas(std::span<const uint8_t>(bytes).first(cut), back, "test"), FormatError) << cut;
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(decodeDeltas(longer, back, "test"), FormatError);
  std::vector<uint8_t> other = bytes;
  other[0] ^= 1;
  EXPECT_THROW(decodeDeltas(other, back, "test"), FormatError);
  std::vector<uint8_t> level = bytes;
  level[4 + 8 + 8] = 9;  // the cube level
  EXPECT_THROW(decodeDeltas(level, back, "test"), FormatError);
  VoxelDeltas empty;
  decodeDeltas(encodeDeltas(VoxelDeltas{}), empty, "test");
  EXPECT_TRUE(empty.keys.empty());
  EXPECT_TRUE(empty.cube_keys.empty());
}

TEST(DroppedPointsWarnings, OnlyPastATenthOfTheValidPoints) {
  IntegratorSettings settings;
  settings.max_range_m = 2.5;
  IntegrationStats stats;
  stats.points = 90;
  stats.points_invalid = 500;  // NaN and zero depth are not the limits' doing: not counted
  stats.points_out_of_range = 10;  // 10 of 100 valid: exactly a tenth
  EXPECT_TRUE(droppedPointsWarnings(stats, settings).empty());
  stats.points_out_of_range = 11;  // 11 of 101
  auto lines = droppedPointsWarnings(stats, settings);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].rfind("11 of 101 valid points (10.9%) lie beyond --max-range 2.5 m; they were dropped", 0), 0u)
      << lines[0];
  settings.carve_beyond_range = true;
  lines = droppedPointsWarnings(stats, settings);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("the free space before them is kept"), std::string::npos) << lines[0];
  stats.points_out_of_range = 0;
  stats.points_outside_map = 50;  // 50 of 140
  lines = droppedPointsWarnings(stats, settings);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].rfind("50 of 140 valid points (35.7%) fall outside the map's extent", 0), 0u) << lines[0];
  EXPECT_TRUE(droppedPointsWarnings(IntegrationStats{}, settings).empty());
}

}  // namespace
}  // namespace chronomap
