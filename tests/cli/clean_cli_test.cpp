// chronomap clean on a simulated dynamic-map sequence (simulate --format dynamic-map), scored as
// the benchmark scores it; its errors.

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "chronomap/ingest/cloud_io.h"
#include "chronomap/sim/dynamic_map.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::cli;

TEST(CleanCli, SimulatedPeopleAreRemovedAndTheRoomKept) {
  test::TempDir tmp;
  const fs::path seq = tmp / "seq";
  auto sim = test::runCommand(cli() + " simulate --format dynamic-map --frames 24 --people 2 --resolution-scale 0.1 "
                                      "--seed 3 --json -o " + seq.string());
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const auto simulated = nlohmann::json::parse(sim.out);
  EXPECT_EQ(simulated["frames"], 24);
  EXPECT_GT(simulated["gt_dynamic"].get<size_t>(), 50u);
  EXPECT_TRUE(fs::exists(seq / "pcd" / "000023.pcd"));
  const auto formats = test::runCommand(cli() + " integrate --list-formats");
  EXPECT_NE(formats.out.find("dynamic-map"), std::string::npos) << formats.out;

  const fs::path out = tmp / "clean.pcd";
  const auto r = test::runCommand(cli() + " clean " + seq.string() + " -o " + out.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto counts = nlohmann::json::parse(r.out);
  EXPECT_EQ(counts["format"], "dynamic-map");
  EXPECT_EQ(counts["frames"], 24);
  EXPECT_GT(counts["points_dynamic"].get<size_t>(), 0u);
  PcdExtras gt;
  const PointCloud truth = readPcd(seq / "gt_cloud.pcd", gt);
  const PointCloud map = readPcd(out);
  EXPECT_EQ(map.points.size(), counts["points_kept"].get<size_t>());
  const StaticMapScores s = scoreStaticMap(truth, gt.intensity, map);
  EXPECT_GE(s.staticAccuracy(), 0.99);
  EXPECT_GE(s.dynamicAccuracy(), 0.9);
}

TEST(CleanCli, ABadViewpointStopsWithTheFileNamedAndNothingWritten) {
  test::TempDir tmp;
  fs::create_directories(tmp / "seq" / "pcd");
  std::ofstream(tmp / "seq" / "pcd" / "000000.pcd")
      << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
      << "VIEWPOINT 0 0 0 1 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n";
  const auto r = test::runCommand(cli() + " clean " + (tmp / "seq").string() + " -o " + (tmp / "c.pcd").string());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("000000.pcd: PCD VIEWPOINT has 6 values"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "c.pcd"));
  const auto ply = test::runCommand(cli() + " clean " + (tmp / "seq").string() + " -o " + (tmp / "c.ply").string());
  EXPECT_EQ(ply.exit_code, 2) << ply.err;
  EXPECT_NE(ply.err.find("must end in .pcd"), std::string::npos) << ply.err;
  const auto help = test::runCommand(cli() + " clean --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("VIEWPOINT"), std::string::npos);
}

}  // namespace
}  // namespace chronomap
