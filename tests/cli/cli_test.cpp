// The command-line contract: exit codes, error messages, JSON keys, files written or not.

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "chronomap/store/cmap.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::cli;

TEST(Cli, HelpForEveryCommand) {
  for (const char* cmd : {"", "integrate", "stats", "export"}) {
    const auto r = test::runCommand(cli() + " " + cmd + " --help");
    EXPECT_EQ(r.exit_code, 0) << cmd;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << cmd;
  }
}

TEST(Cli, BadUsageExitsWithTwo) {
  test::TempDir tmp;
  for (const std::string args : {"", "frobnicate", "integrate", "integrate x", "integrate x -o y.cmap --bogus",
                                 "stats", "export a.cmap"}) {
    const auto r = test::runCommand(cli() + " " + args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("chronomap: error: ", 0), 0u) << args << "\n" << r.err;
  }
  const auto r = test::runCommand(cli() + " integrate " + tmp.path().string() + " -o " + (tmp / "o.cmap").string() +
                                  " --resolution -1");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "o.cmap"));
}

TEST(Cli, UpTurnsTheRecordingAndABadOneNamesTheFlag) {
  test::TempDir tmp;
  const std::string wall = test::writeWallDataset(tmp.path(), "wall", 2.0f).string();
  for (const std::string& cmd : {"integrate " + wall + " -o " + (tmp / "o.cmap").string(),
                                 "build " + (tmp / "m.cmap").string() + " " + wall + " --times 0"}) {
    const auto bad = test::runCommand(cli() + " " + cmd + " --up sideways");
    EXPECT_EQ(bad.exit_code, 2) << cmd;
    EXPECT_NE(bad.err.find("--up must be +x, -x, +y, -y, +z, -z or auto, not 'sideways'"), std::string::npos)
        << bad.err;
  }
  EXPECT_FALSE(fs::exists(tmp / "o.cmap"));
  EXPECT_FALSE(fs::exists(tmp / "m.cmap"));
  // The wall at x = 2 m seen from the origin, with +x up, lies 2 m above the sensor.
  const auto r = test::runCommand(cli() + " integrate " + wall + " -o " + (tmp / "o.cmap").string() + " --up +x --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["up"], "+x");
  const auto s = test::runCommand(cli() + " stats " + (tmp / "o.cmap").string() + " --json");
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const auto j = nlohmann::json::parse(s.out);
  EXPECT_EQ(j["metadata"]["up"], "+x");
  EXPECT_NEAR(j["bounds_max"][2].get<double>(), 2.0, 0.1);
  EXPECT_LT(j["bounds_max"][0].get<double>(), 0.6);
}

// --up auto on the study room: +y, and --json says what the text says (the floor's share of the
// sampled cells; scripts/make-doc-images.sh quotes both in docs/frames.md).
TEST(Cli, UpAutoOnTheStudyRoomPrintsTheFloorItFoundInTextAndJson) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  const std::string cmd = cli() + " integrate " + root.string() + " --resolution 0.04 --max-range 6 --up auto -o " +
                          (tmp / "room.cmap").string();
  const auto r = test::runCommand(cmd + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["up"], "+y");
  EXPECT_EQ(j["up_from"], "auto");
  const double share = j["up_floor_share"].get<double>();
  const uint64_t cells = j["up_sampled_cells"].get<uint64_t>();
  EXPECT_GT(share, 0.0);
  EXPECT_LT(share, 1.0);
  EXPECT_GT(cells, 1000u);
  const auto t = test::runCommand(cmd);
  ASSERT_EQ(t.exit_code, 0) << t.err;
  const std::string said = "a floor of " + std::to_string(static_cast<int>(std::lround(100 * share))) + "% of " +
                           std::to_string(cells) + " sampled cells";
  EXPECT_NE(t.out.find(said), std::string::npos) << said << "\n" << t.out;
}

// --depth-edges on real depth images: points at depth steps are dropped and counted apart, every
// pixel is still accounted for, and a negative ratio is refused before anything is written.
TEST(Cli, DepthEdgesDropsAndCountsThePointsAtDepthStepsOfRealFrames) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  const std::string base = cli() + " integrate " + root.string() + " --max-range 6 -o " + (tmp / "room.cmap").string();
  const auto off = test::runCommand(base + " --json");
  const auto on = test::runCommand(base + " --depth-edges 0.05 --json");
  ASSERT_EQ(off.exit_code, 0) << off.err;
  ASSERT_EQ(on.exit_code, 0) << on.err;
  const auto a = nlohmann::json::parse(off.out), b = nlohmann::json::parse(on.out);
  EXPECT_EQ(a["points_depth_edges"], 0);
  const uint64_t dropped = b["points_depth_edges"].get<uint64_t>();
  EXPECT_GT(dropped, 1000u);
  EXPECT_LT(dropped, 5u * 640u * 480u / 5u);  // edges, not the picture
  EXPECT_EQ(b["points"].get<uint64_t>() + b["points_skipped"].get<uint64_t>(), 5u * 640u * 480u);
  EXPECT_EQ(b["points_invalid"], a["points_invalid"]);
  EXPECT_LT(b["occupied"].get<uint64_t>(), a["occupied"].get<uint64_t>());
  const auto bad = test::runCommand(base + " --depth-edges -0.1");
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
}

TEST(Cli, IntegrateStatsExportOnRealFrames) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  const auto r = test::runCommand(cli() + " integrate " + root.string() + " -o " + (tmp / "room.cmap").string() +
                                  " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"frames", "points", "points_skipped", "occupied", "free", "seconds"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["frames"], 5);
  EXPECT_EQ(j["points"].get<uint64_t>() + j["points_skipped"].get<uint64_t>(), 5u * 640u * 480u);
  EXPECT_GT(j["occupied"].get<uint64_t>(), 1000u);

  const auto s = test::runCommand(cli() + " stats " + (tmp / "room.cmap").string() + " --json");
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const auto js = nlohmann::json::parse(s.out);
  for (const char* key : {"kind", "resolution_m", "sessions", "times", "nodes", "bytes", "nodes_separate"}) {
    EXPECT_TRUE(js.contains(key)) << key;
  }
  EXPECT_EQ(js["kind"], "session");
  EXPECT_EQ(js["occupied"], j["occupied"]);
  EXPECT_DOUBLE_EQ(js["resolution_m"].get<double>(), 0.05);

  const auto human = test::runCommand(cli() + " stats " + (tmp / "room.cmap").string());
  EXPECT_EQ(human.exit_code, 0);
  EXPECT_NE(human.out.find("occupied"), std::string::npos);

  for (const char* ext : {"ply", "ot", "png"}) {
    const fs::path out = tmp / (std::string("room.") + ext);
    const auto e = test::runCommand(cli() + " export " + (tmp / "room.cmap").string() + " -o " + out.string());
    EXPECT_EQ(e.exit_code, 0) << e.err;
    EXPECT_GT(fs::file_size(out), 1000u);
  }
}

// Hit positions: recorded by default (every occupied voxel's offsets lie within half a voxel per
// hit and are not all zero), none with --no-positions; the rest of the map is the same.
TEST(Cli, IntegrateSaysWhenTheRangeDropsMoreThanATenthOfThePoints) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  // The default 3 m drops about half of these frames' points: stderr and --json say so.
  const auto r = test::runCommand(cli() + " integrate " + root.string() + " -o " + (tmp / "a.cmap").string() +
                                  " --fast --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const uint64_t beyond = j["points_out_of_range"].get<uint64_t>();
  ASSERT_GT(beyond, j["points"].get<uint64_t>() / 10);
  ASSERT_EQ(j["warnings"].size(), 1u);
  const std::string warning = j["warnings"][0].get<std::string>();
  EXPECT_NE(warning.find(std::to_string(beyond) + " of "), std::string::npos) << warning;
  EXPECT_NE(warning.find("--max-range 3 m"), std::string::npos) << warning;
  EXPECT_NE(r.err.find("chronomap: warning: " + root.string() + ": " + warning), std::string::npos) << r.err;
  // A range that keeps them says nothing.
  const auto far = test::runCommand(cli() + " integrate " + root.string() + " -o " + (tmp / "b.cmap").string() +
                                    " --fast --max-range 10 --json");
  ASSERT_EQ(far.exit_code, 0) << far.err;
  EXPECT_TRUE(nlohmann::json::parse(far.out)["warnings"].empty());
  EXPECT_EQ(far.err.find("warning"), std::string::npos) << far.err;
}

TEST(Cli, IntegrateRecordsHitPositionsUnlessToldNot) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  for (const char* extra : {"", " --no-positions"}) {
    const fs::path out = tmp / (extra[0] ? "bare.cmap" : "room.cmap");
    const auto r = test::runCommand(cli() + " integrate " + root.string() + " --fast -o " + out.string() + extra);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const CmapFile file = readCmap(tmp / "room.cmap");
  EXPECT_EQ(metadataOf(file)["hit_positions"], true);
  EXPECT_EQ(metadataOf(readCmap(tmp / "bare.cmap"))["hit_positions"], false);
  const SessionMap with = sessionMapFrom(file, "room.cmap"), bare = readSessionMap(tmp / "bare.cmap");
  const std::vector<VoxelCounters> with_leaves = with.pools().leaves, bare_leaves = bare.pools().leaves;
  ASSERT_EQ(with_leaves.size(), bare_leaves.size());
  size_t placed = 0;
  for (size_t i = 0; i < with_leaves.size(); ++i) {
    VoxelCounters a = with_leaves[i];
    const VoxelCounters& b = bare_leaves[i];
    EXPECT_TRUE(a.offsetsValid());
    placed += a.hits > 0 && (a.offset[0] != 0.0f || a.offset[1] != 0.0f || a.offset[2] != 0.0f);
    for (float o : b.offset) EXPECT_EQ(o, 0.0f);
    for (float& o : a.offset) o = 0.0f;
    ASSERT_EQ(a, b) << "leaf " << i;
  }
  EXPECT_GT(placed, 1000u);
}

// Coarse carving: --carve-level with --fast is recorded in the metadata and keeps the hits;
// without --fast it is refused.
TEST(Cli, IntegrateCarvesCoarserWhenAsked) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  auto r = test::runCommand(cli() + " integrate " + root.string() + " --fast --carve-level 2 -o " +
                            (tmp / "carved.cmap").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = test::runCommand(cli() + " integrate " + root.string() + " --fast -o " + (tmp / "fast.cmap").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(metadataOf(readCmap(tmp / "carved.cmap"))["carve_level"], 2);
  EXPECT_FALSE(metadataOf(readCmap(tmp / "fast.cmap")).contains("carve_level"));  // auto: 0 at 0.05 m
  const double occupied = static_cast<double>(readSessionMap(tmp / "fast.cmap").counts().occupied_voxels);
  EXPECT_NEAR(static_cast<double>(readSessionMap(tmp / "carved.cmap").counts().occupied_voxels), occupied,
              0.01 * occupied);
  r = test::runCommand(cli() + " integrate " + root.string() + " --carve-level 2 -o " + (tmp / "x.cmap").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("needs fast mode"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "x.cmap"));
  for (const char* bad : {"5", "x", "-1", "22"}) {
    r = test::runCommand(cli() + " integrate " + root.string() + " --fast --carve-level " + bad + " -o " +
                         (tmp / "x.cmap").string());
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.err.find("--carve-level must be auto or a level from 0 to 4"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(tmp / "x.cmap"));
  }
  // The default, auto, carves at level 2 at 0.02 m, and records it.
  r = test::runCommand(cli() + " integrate " + root.string() + " --fast --resolution 0.02 -o " +
                       (tmp / "fine.cmap").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(metadataOf(readCmap(tmp / "fine.cmap"))["carve_level"], 2);
}

TEST(Cli, BadDataExitsWithOneAndWritesNothing) {
  test::TempDir tmp;
  std::ofstream(tmp / "broken.cmap") << "definitely not a map";
  auto r = test::runCommand(cli() + " stats " + (tmp / "broken.cmap").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("broken.cmap"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("wrong magic"), std::string::npos) << r.err;

  r = test::runCommand(cli() + " export " + (tmp / "broken.cmap").string() + " -o " + (tmp / "x.ply").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(tmp / "x.ply"));

  // A cloud whose points are all NaN: nothing to integrate, nothing written.
  std::ofstream(tmp / "nan.xyz") << "nan nan nan\ninf 0 0\n";
  r = test::runCommand(cli() + " integrate " + (tmp / "nan.xyz").string() + " -o " + (tmp / "n.cmap").string());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("no valid points"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "n.cmap"));

  // A bad pose in a cloud list names the file and line.
  std::ofstream(tmp / "ok.xyz") << "1 0 0\n";
  std::ofstream(tmp / "list.txt") << "ok.xyz 0 0 0 0 0 0 0\n";
  r = test::runCommand(cli() + " integrate " + (tmp / "list.txt").string() + " -o " + (tmp / "l.cmap").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("list.txt:1: pose quaternion is zero"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "l.cmap"));

  // An existing map is not damaged by a failed run that targets it.
  std::ofstream(tmp / "keep.cmap") << "old content";
  r = test::runCommand(cli() + " integrate " + (tmp / "list.txt").string() + " -o " + (tmp / "keep.cmap").string());
  EXPECT_EQ(r.exit_code, 1);
  std::ifstream keep(tmp / "keep.cmap");
  std::string content((std::istreambuf_iterator<char>(keep)), std::istreambuf_iterator<char>());
  EXPECT_EQ(content, "old content");
}

TEST(Cli, SingleCloudWithPoseOption) {
  test::TempDir tmp;
  std::ofstream(tmp / "p.xyz") << "1 0 0\n0 1 0\n";
  const auto r = test::runCommand(cli() + " integrate " + (tmp / "p.xyz").string() + " -o " +
                                  (tmp / "p.cmap").string() + " --pose 0.5,0,0,0,0,0,1 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["points"], 2);
  const auto bad = test::runCommand(cli() + " integrate " + (tmp / "p.xyz").string() + " -o " +
                                    (tmp / "q.cmap").string() + " --pose 1,2,3");
  EXPECT_EQ(bad.exit_code, 2);
}

}  // namespace
}  // namespace chronomap
