// Costmaps and the planner (analysis/costmap.h) and their map_server files (export/map_server.h):
// analytic maps, slow references on random grids (Dijkstra, disk inflation), the files loaded by
// map_server's documented rules, bad settings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <sstream>

#include "builders.h"
#include "chronomap/analysis/costmap.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/export/map_server.h"
#include "test_support.h"

namespace chronomap {
namespace {

using test::at;
using test::freeVoxel;
using test::occupiedVoxel;
namespace fs = std::filesystem;

/// A 20 x 10 voxel floor area (z keys 2..10, about 0.1..0.55 m at 0.05 m) seen free, with a
/// wall of occupied voxels at x = 10 for y in 0..7, leaving a gap at y = 8, 9.
SessionMap room() {
  SessionMap m(0.05);
  const int z0 = 32768;  // key of z = 0
  for (int x = 0; x < 20; ++x) {
    for (int y = 0; y < 10; ++y) {
      for (int z = 2; z < 10; ++z) {
        const bool wall = x == 10 && y < 8;
        m.add(VoxelKey{static_cast<uint16_t>(32768 + x), static_cast<uint16_t>(32768 + y), static_cast<uint16_t>(z0 + z)},
              wall ? occupiedVoxel(Rgb{}) : freeVoxel());
      }
    }
  }
  return m;
}

TEST(Costmap, WallsAreLethalAndInflatedByTheRadius) {
  CostmapSettings s;
  s.z_min_m = 0.05;
  s.z_max_m = 1.0;
  s.robot_radius_m = 0.1;  // two cells
  const Costmap c = costmap(room(), s);
  ASSERT_EQ(c.width, 20);
  ASSERT_EQ(c.height, 10);
  EXPECT_NEAR(c.origin_m.x(), 0.0, 1e-9);
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 20; ++x) {
      const bool wall = x == 10 && y < 8;
      // Within two cells (centre to centre) of a wall cell.
      bool near = false;
      for (int wy = 0; wy < 8; ++wy) near |= (x - 10) * (x - 10) + (y - wy) * (y - wy) <= 4;
      const int8_t expected = wall ? Costmap::kLethal : near ? Costmap::kInscribed : 0;
      EXPECT_EQ(c.at(x, y), expected) << x << "," << y;
    }
  }
  // A band above the wall's voxels sees nothing: everything unknown there is outside the map.
  s.z_min_m = 2.0;
  s.z_max_m = 3.0;
  EXPECT_EQ(costmap(room(), s).width, 0);
  s.z_max_m = 1.0;
  EXPECT_THROW(costmap(room(), s), UsageError);
  s = CostmapSettings{};
  s.robot_radius_m = -1;
  EXPECT_THROW(costmap(room(), s), UsageError);
}

TEST(Costmap, ProbabilityAndChangeRaiseTheCost) {
  SessionMap m(0.05);
  const auto key = [](int x) { return VoxelKey{static_cast<uint16_t>(32768 + x), 32768, 32770}; };
  VoxelCounters quarter;  // P = 1 - exp(-hits / length) = 0.25
  quarter.hits = 1;
  quarter.length_m = static_cast<float>(-1.0 / std::log(0.75));
  m.add(key(0), freeVoxel());
  m.add(key(1), quarter);
  CostmapSettings s;
  s.robot_radius_m = 0.0;
  s.change_weight = 0.5;
  Costmap c = costmap(m, s);
  ASSERT_EQ(c.width, 2);
  EXPECT_EQ(c.at(0, 0), 0);
  EXPECT_EQ(c.at(1, 0), std::lround(98 * 0.5 * (0.25 / 0.5)));  // probability half weighted
  // A voxel that was occupied in half its observations changes most: its column costs more.
  RhythmModels models;
  models.resolution_m = 0.05;
  VoxelRhythm v;
  v.corner = key(0);
  v.mean = 0.5f;
  models.voxels.push_back(v);
  c = costmap(m, s, &models);
  EXPECT_EQ(c.at(0, 0), std::lround(98 * 0.5 * 1.0));
}

TEST(Costmap, TheLethalProbabilityMovesTheObstacleThreshold) {
  // A voxel occupied with P = 0.6: an obstacle at the default threshold of 0.5; at 0.7 passable,
  // costing 98 x 0.6 / 0.7 (no change weight).
  SessionMap m(0.05);
  VoxelCounters six_tenths;
  six_tenths.hits = 1;
  six_tenths.length_m = static_cast<float>(-1.0 / std::log(0.4));
  m.add(VoxelKey{32768, 32768, 32770}, six_tenths);
  CostmapSettings s;
  s.robot_radius_m = 0.0;
  s.change_weight = 0.0;
  EXPECT_EQ(costmap(m, s).at(0, 0), Costmap::kLethal);
  s.lethal_probability = 0.7;
  EXPECT_EQ(costmap(m, s).at(0, 0), std::lround(98 * 0.6 / 0.7));
  s.lethal_probability = 0.55;
  EXPECT_EQ(costmap(m, s).at(0, 0), Costmap::kLethal);
  for (double bad : {0.0, 1.0, -0.5, std::nan("")}) {
    s.lethal_probability = bad;
    EXPECT_THROW(costmap(m, s), UsageError) << bad;
  }
}

TEST(Costmap, AModelledVoxelSeenOccupiedTooRarelyIsNoObstacle) {
  // Three voxels predicted occupied with P = 0.9 in a row: (0) modelled, occupied in 1 of 21
  // learning sessions (a stray hit); (1) modelled, occupied in 3 of 20; (2) never changed, so not
  // modelled. With min_occupied_sessions 3 only the stray one is held at the threshold: passable,
  // costing 98 x (0.5 x 0.5 / 0.5 + 0.5 x its change share 4m(1 - m)).
  SessionMap m(0.05);
  const auto key = [](int x) { return VoxelKey{static_cast<uint16_t>(32768 + x), 32768, 32770}; };
  VoxelCounters likely;  // P = 0.9
  likely.hits = 1;
  likely.length_m = static_cast<float>(-1.0 / std::log(0.1));
  for (int x = 0; x < 3; ++x) m.add(key(x), likely);
  RhythmModels models;
  models.resolution_m = 0.05;
  VoxelRhythm stray, thrice;
  stray.corner = key(0);
  stray.observations = 21;
  stray.mean = 1.0f / 21.0f;
  thrice.corner = key(1);
  thrice.observations = 20;
  thrice.mean = 3.0f / 20.0f;
  models.voxels = {stray, thrice};
  CostmapSettings s;
  s.robot_radius_m = 0.0;
  Costmap c = costmap(m, s, &models);  // off by default: all three lethal
  ASSERT_EQ(c.width, 3);
  for (int x = 0; x < 3; ++x) EXPECT_EQ(c.at(x, 0), Costmap::kLethal) << x;
  for (uint32_t off : {0u, 1u}) {
    s.min_occupied_sessions = off;
    EXPECT_EQ(costmap(m, s, &models).cost, c.cost) << off;
  }
  s.min_occupied_sessions = 3;
  c = costmap(m, s, &models);
  const double share = 4.0 * (1.0 / 21.0) * (1.0 - 1.0 / 21.0);
  EXPECT_EQ(c.at(0, 0), std::lround(98.0 * (0.5 * 1.0 + 0.5 * share)));
  EXPECT_EQ(c.at(1, 0), Costmap::kLethal);
  EXPECT_EQ(c.at(2, 0), Costmap::kLethal);
  s.min_occupied_sessions = 4;  // now the voxel seen occupied three times is held too
  EXPECT_LT(costmap(m, s, &models).at(1, 0), Costmap::kInscribed);
  // Without models the rule has nothing to read: every voxel as before.
  EXPECT_EQ(costmap(m, s).at(0, 0), Costmap::kLethal);
}

TEST(Costmap, MapServerFilesFollowTheConventions) {
  test::TempDir tmp;
  Costmap c;
  c.resolution_m = 0.05;
  c.origin_m = {1.5, -2.0};
  c.width = 3;
  c.height = 2;
  c.cost = {0, 50, 100, -1, 99, 0};  // row y = 0, then y = 1
  const auto pgm = writeMapServer(tmp / "cost.yaml", c);
  EXPECT_EQ(pgm, tmp / "cost.pgm");
  const std::string yaml = readTextFile(tmp / "cost.yaml");
  for (const char* field : {"image: cost.pgm\n", "resolution: 0.050000\n", "origin: [1.500000, -2.000000, 0.0]\n",
                            "negate: 0\n", "occupied_thresh: 0.65\n", "free_thresh: 0.196\n", "mode: raw\n"}) {
    EXPECT_NE(yaml.find(field), std::string::npos) << field;
  }
  const std::vector<uint8_t> bytes = readFileBytes(pgm);
  const std::string header = "P5\n3 2\n255\n";
  ASSERT_EQ(bytes.size(), header.size() + 6);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + static_cast<long>(header.size())), header);
  // First image row is the highest y: each grey level is the cost, 255 unknown.
  const std::vector<uint8_t> pixels(bytes.begin() + static_cast<long>(header.size()), bytes.end());
  EXPECT_EQ(pixels, (std::vector<uint8_t>{255, 99, 0, 0, 50, 100}));
}

/// The map_server loaders whose documented rules the files must satisfy, for a one-channel
/// (PGM) image: ROS 1 map_server's image_loader before Noetic (scale: 99 r, truncated) and in
/// Noetic (1 + 98 r, truncated), and ROS 2 nav2_map_server's map_io (rint(100 r)). In ROS 1 a
/// one-channel pixel's alpha is 1, so scale mode never reads it unknown; nav2 reads a PGM as
/// opaque. Raw mode: ROS 1 stores the grey level as a signed byte, nav2 keeps 0..100 and reads
/// anything above as unknown.
enum class Loader { kRos1Scale99, kRos1Noetic, kNav2 };

struct LoadedMap {
  int width = 0, height = 0;
  double resolution_m = 0;
  std::vector<int> cells;  ///< row-major from the lowest y, as the OccupancyGrid message
};

LoadedMap loadMapServer(const fs::path& yaml_path, Loader loader) {
  std::map<std::string, std::string> yaml;
  std::istringstream lines(readTextFile(yaml_path));
  for (std::string line; std::getline(lines, line);) {
    const size_t colon = line.find(": ");
    if (colon != std::string::npos) yaml[line.substr(0, colon)] = line.substr(colon + 2);
  }
  const std::string mode = yaml.count("mode") ? yaml["mode"] : "trinary";
  const bool negate = yaml["negate"] == "1" || yaml["negate"] == "true";
  const double occupied = std::stod(yaml.at("occupied_thresh")), free = std::stod(yaml.at("free_thresh"));
  EXPECT_TRUE(mode == "trinary" || mode == "scale" || mode == "raw") << mode;
  const std::vector<uint8_t> bytes = readFileBytes(yaml_path.parent_path() / yaml.at("image"));
  std::istringstream header(std::string(bytes.begin(), bytes.begin() + static_cast<long>(std::min<size_t>(bytes.size(), 64))));
  std::string magic;
  LoadedMap out;
  int max_grey = 0;
  header >> magic >> out.width >> out.height >> max_grey;
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(max_grey, 255);
  const size_t first = static_cast<size_t>(header.tellg()) + 1;  // one whitespace after the header
  EXPECT_EQ(bytes.size(), first + static_cast<size_t>(out.width * out.height));
  out.resolution_m = std::stod(yaml.at("resolution"));
  out.cells.assign(static_cast<size_t>(out.width * out.height), 0);
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      const double grey = bytes[first + static_cast<size_t>(y * out.width + x)];
      int value = 0;
      if (loader == Loader::kNav2) {
        const double shade = grey / 255.0, occ = negate ? shade : 1.0 - shade;
        if (mode == "raw") {
          const double level = std::round(shade * 255.0);
          value = level >= 0 && level <= 100 ? static_cast<int>(level) : -1;
        } else if (occupied < occ) {
          value = 100;
        } else if (occ < free) {
          value = 0;
        } else {
          value = mode == "trinary" ? -1 : static_cast<int>(std::rint((occ - free) / (occupied - free) * 100.0));
        }
      } else {
        const double average = negate ? 255.0 - grey : grey;
        const double occ = (255.0 - average) / 255.0, ratio = (occ - free) / (occupied - free);
        if (mode == "raw") {
          value = static_cast<int8_t>(static_cast<uint8_t>(average));
        } else if (occ > occupied) {
          value = 100;
        } else if (occ < free) {
          value = 0;
        } else if (mode == "trinary") {
          value = -1;
        } else {
          value = static_cast<uint8_t>(loader == Loader::kRos1Scale99 ? 99 * ratio : 1 + 98 * ratio);
        }
      }
      out.cells[static_cast<size_t>((out.height - 1 - y) * out.width + x)] = value;  // first row: highest y
    }
  }
  return out;
}

TEST(Costmap, MapServerLoadersReadEveryCostAsChronomapMeansIt) {
  // Every value a costmap holds (unknown, free, each cost, inscribed, lethal), in two rows of
  // opposite order, loaded by each loader's documented rules: each cell must come back as it is.
  // (Before, mode scale with 205 for unknown: all three loaded unknown as free or as cost 1, and
  // every cost up to 20 as free.)
  test::TempDir tmp;
  Costmap c;
  c.resolution_m = 0.02;
  c.width = 102;
  c.height = 2;
  for (int v = -1; v <= 100; ++v) c.cost.push_back(static_cast<int8_t>(v));
  for (int v = 100; v >= -1; --v) c.cost.push_back(static_cast<int8_t>(v));
  writeMapServer(tmp / "cost.yaml", c);
  const std::vector<int> expected(c.cost.begin(), c.cost.end());
  for (Loader loader : {Loader::kRos1Scale99, Loader::kRos1Noetic, Loader::kNav2}) {
    const LoadedMap m = loadMapServer(tmp / "cost.yaml", loader);
    ASSERT_EQ(m.width, c.width);
    ASSERT_EQ(m.height, c.height);
    EXPECT_DOUBLE_EQ(m.resolution_m, 0.02);
    EXPECT_EQ(m.cells, expected) << "loader " << static_cast<int>(loader);
  }
}

/// Today's inflation before the distance transform, kept as the slow reference: a disk of offsets
/// stamped around every lethal cell.
void inflateByDisk(Costmap& m, double radius_m) {
  const double r = m.resolution_m;
  const int reach = static_cast<int>(std::floor(radius_m / r + 1e-9));
  std::vector<Eigen::Vector2i> disk;
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      if ((dx || dy) && (dx * dx + dy * dy) * r * r <= radius_m * radius_m + 1e-12) disk.emplace_back(dx, dy);
    }
  }
  const Costmap before = m;
  for (int j = 0; j < m.height; ++j) {
    for (int i = 0; i < m.width; ++i) {
      if (before.at(i, j) != Costmap::kLethal) continue;
      for (const Eigen::Vector2i& d : disk) {
        const int x = i + d.x(), y = j + d.y();
        if (x < 0 || y < 0 || x >= m.width || y >= m.height) continue;
        if (m.at(x, y) != Costmap::kLethal) m.at(x, y) = Costmap::kInscribed;
      }
    }
  }
}

TEST(Costmap, InflationMatchesTheDiskReferenceOnRandomGrids) {
  // Random grids (from one cell to 40 x 30, every tenth up to 160 x 120; sparse to dense
  // obstacles, unknown cells), resolutions and radii, including radii on whole and diagonal cell
  // distances, where rounding decides.
  const double resolutions[] = {0.01, 0.02, 0.03, 0.05, 0.1, 0.25};
  size_t inscribed = 0;
  for (uint64_t seed = 0; seed < 400; ++seed) {
    std::mt19937_64 rng(seed);
    Costmap m;
    m.resolution_m = resolutions[rng() % 6];
    const int scale = seed % 10 == 9 ? 4 : 1;
    m.width = 1 + static_cast<int>(rng() % static_cast<uint64_t>(40 * scale));
    m.height = 1 + static_cast<int>(rng() % static_cast<uint64_t>(30 * scale));
    const auto density = rng() % 100;  // per mille of lethal cells: 0 .. 99
    m.cost.resize(static_cast<size_t>(m.width * m.height));
    for (auto& c : m.cost) {
      c = rng() % 1000 < density ? Costmap::kLethal : rng() % 8 == 0 ? Costmap::kUnknown : static_cast<int8_t>(rng() % 99);
    }
    const double cells = static_cast<double>(rng() % 12);
    const double radius = seed % 3 == 0 ? cells * m.resolution_m
                          : seed % 3 == 1 ? std::sqrt(cells * cells + static_cast<double>(rng() % 4)) * m.resolution_m
                                          : std::uniform_real_distribution<double>(0.0, 0.6)(rng);
    Costmap fast = m, slow = m;
    inflate(fast, radius);
    inflateByDisk(slow, radius);
    ASSERT_EQ(fast.cost, slow.cost) << "seed " << seed << ", radius " << radius << " m at " << m.resolution_m;
    inscribed += static_cast<size_t>(std::count(fast.cost.begin(), fast.cost.end(), Costmap::kInscribed));
  }
  EXPECT_GT(inscribed, 10000u);  // the trials inflate, not only pass through
}

TEST(Costmap, InflationMemoryDoesNotGrowWithTheRadius) {
  // A 100 m radius on a 0.01 m grid (--robot-radius 100 on a 1 cm map): the disk of offsets took
  // (2 x 10^4)^2 x 8 bytes = 3.2 GB and ran out of memory. Within 256 MiB now, every cell but the
  // lethal one inscribed; a 0.02 m radius marks the cells two apart or nearer.
  const int code = test::exitCodeUnderMemoryLimit(size_t{256} << 20, [] {
    Costmap m;
    m.resolution_m = 0.01;
    m.width = 60;
    m.height = 40;
    m.cost.assign(60 * 40, 0);
    m.at(30, 20) = Costmap::kLethal;
    Costmap wide = m;
    inflate(wide, 100.0);
    if (std::count(wide.cost.begin(), wide.cost.end(), Costmap::kInscribed) != 60 * 40 - 1) return 1;
    inflate(m, 0.02);
    return std::count(m.cost.begin(), m.cost.end(), Costmap::kInscribed) == 12 ? 0 : 2;
  });
  EXPECT_EQ(code, 0) << "99: out of memory";
}

/// The slow reference: Dijkstra over every cell with the same step costs.
double dijkstra(const Costmap& m, const Eigen::Vector2i& s, const Eigen::Vector2i& g) {
  std::vector<double> d(m.cost.size(), std::numeric_limits<double>::infinity());
  std::vector<bool> done(m.cost.size(), false);
  auto id = [&](int x, int y) { return static_cast<size_t>(y * m.width + x); };
  d[id(s.x(), s.y())] = 0;
  for (;;) {
    size_t best = m.cost.size();
    for (size_t i = 0; i < m.cost.size(); ++i) {
      if (!done[i] && std::isfinite(d[i]) && (best == m.cost.size() || d[i] < d[best])) best = i;
    }
    if (best == m.cost.size()) break;
    done[best] = true;
    const int x = static_cast<int>(best) % m.width, y = static_cast<int>(best) / m.width;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if ((!dx && !dy) || nx < 0 || ny < 0 || nx >= m.width || ny >= m.height) continue;
        const int8_t c = m.at(nx, ny);
        if (c < 0 || c >= Costmap::kInscribed) continue;
        const double step = (dx && dy ? std::sqrt(2.0) : 1.0) * (1.0 + c / 25.0);
        d[id(nx, ny)] = std::min(d[id(nx, ny)], d[best] + step);
      }
    }
  }
  return d[id(g.x(), g.y())];
}

double pathCost(const Costmap& m, const std::vector<Eigen::Vector2i>& p) {
  double total = 0;
  for (size_t i = 1; i < p.size(); ++i) {
    const Eigen::Vector2i d = p[i] - p[i - 1];
    EXPECT_LE(d.cwiseAbs().maxCoeff(), 1);
    const int8_t c = m.at(p[i].x(), p[i].y());
    EXPECT_TRUE(c >= 0 && c < Costmap::kInscribed);
    total += (d.x() && d.y() ? std::sqrt(2.0) : 1.0) * (1.0 + c / 25.0);
  }
  return total;
}

TEST(Costmap, PlannerFindsTheCheapestPathOnRandomGrids) {
  for (uint64_t seed = 0; seed < 40; ++seed) {
    std::mt19937_64 rng(seed);
    Costmap m;
    m.width = 12 + static_cast<int>(rng() % 10);
    m.height = 8 + static_cast<int>(rng() % 8);
    m.cost.resize(static_cast<size_t>(m.width * m.height));
    for (auto& c : m.cost) {
      const auto r = rng() % 10;
      c = r < 2 ? Costmap::kLethal : r < 3 ? Costmap::kUnknown : static_cast<int8_t>(rng() % 90);
    }
    const Eigen::Vector2i s(0, 0), g(m.width - 1, m.height - 1);
    m.at(s.x(), s.y()) = 0;
    m.at(g.x(), g.y()) = 0;
    const double reference = dijkstra(m, s, g);
    const auto path = planPath(m, s, g);
    ASSERT_EQ(path.has_value(), std::isfinite(reference)) << "seed " << seed;
    if (!path) continue;
    EXPECT_EQ(path->front(), s);
    EXPECT_EQ(path->back(), g);
    EXPECT_NEAR(pathCost(m, *path), reference, 1e-9) << "seed " << seed;
  }
}

TEST(Costmap, PlannerGoesThroughTheGap) {
  CostmapSettings s;
  s.robot_radius_m = 0.0;
  const Costmap c = costmap(room(), s);
  const auto path = planPath(c, {2, 2}, {17, 2});
  ASSERT_TRUE(path);
  bool through_gap = false;
  for (const auto& p : *path) through_gap |= p.x() == 10 && p.y() >= 8;
  EXPECT_TRUE(through_gap);
  EXPECT_FALSE(planPath(c, {2, 2}, {10, 2}));   // into the wall
  EXPECT_FALSE(planPath(c, {2, 2}, {50, 2}));   // outside
}

}  // namespace
}  // namespace chronomap
