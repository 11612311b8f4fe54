// Tiled maps on the command line: tile, untile, and snapshot / history / diff given a folder.

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "chronomap/io/cmap.h"
#include "chronomap/io/diff_file.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/io/tiled_file.h"
#include "builders.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;
using test::cli;
using test::runCommand;

TEST(TilesCli, TiledFolderAnswersAsTheMap) {
  test::TempDir tmp;
  TemporalMap map(0.05);
  for (int i = 0; i < 3; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(static_cast<uint64_t>(20 + i), 12));
  io::writeTemporalMap(tmp / "m.cmap", map, {});
  const std::string m = (tmp / "m.cmap").string(), t = (tmp / "t").string();

  const test::CommandResult tiled = runCommand(cli() + " tile " + m + " -o " + t + " --tile-size 0.2 --json");
  ASSERT_EQ(tiled.exit_code, 0) << tiled.err;
  const nlohmann::json tj = nlohmann::json::parse(tiled.out);
  EXPECT_EQ(tj["tile_level"], 2);
  EXPECT_EQ(tj["tiles"], 27);  // 12 voxels per axis from a tile corner: 3 x 3 x 3 tiles of 4

  // The whole snapshot, from the folder and from the file.
  ASSERT_EQ(runCommand(cli() + " snapshot " + t + " --at 2500 -o " + (tmp / "a.cmap").string()).exit_code, 0);
  ASSERT_EQ(runCommand(cli() + " snapshot " + m + " --at 2500 -o " + (tmp / "b.cmap").string()).exit_code, 0);
  EXPECT_TRUE(io::readSessionMap(tmp / "a.cmap") == io::readSessionMap(tmp / "b.cmap"));

  // A box inside one tile reads one tile.
  const test::CommandResult box = runCommand(cli() + " snapshot " + t + " --at 2500 --box 0,0,0,0.15,0.15,0.15 -o " +
                                             (tmp / "c.cmap").string() + " --memory-limit 0.001 --json");
  ASSERT_EQ(box.exit_code, 0) << box.err;
  EXPECT_EQ(nlohmann::json::parse(box.out)["tiles"]["tiles_loaded"], 1);

  // History: the same answer.
  const test::CommandResult h1 = runCommand(cli() + " history " + t + " --point 0.31,0.22,0.1 --json");
  const test::CommandResult h2 = runCommand(cli() + " history " + m + " --point 0.31,0.22,0.1 --json");
  ASSERT_EQ(h1.exit_code, 0) << h1.err;
  EXPECT_EQ(h1.out, h2.out);

  // Diff of two times of the folder, and of the file.
  ASSERT_EQ(runCommand(cli() + " diff " + t + "@1000 " + t + "@3000 -o " + (tmp / "d1.cmap").string()).exit_code, 0);
  ASSERT_EQ(runCommand(cli() + " diff " + m + "@1000 " + m + "@3000 -o " + (tmp / "d2.cmap").string()).exit_code, 0);
  EXPECT_TRUE(io::readDiffMap(tmp / "d1.cmap") == io::readDiffMap(tmp / "d2.cmap"));
  EXPECT_FALSE(io::readDiffMap(tmp / "d1.cmap").empty());

  // Joined back: the same map.
  ASSERT_EQ(runCommand(cli() + " untile " + t + " -o " + (tmp / "back.cmap").string()).exit_code, 0);
  EXPECT_TRUE(io::readTemporalMap(tmp / "back.cmap") == io::readTemporalMap(tmp / "m.cmap"));
}

TEST(TilesCli, BadInputGivesOneLine) {
  test::TempDir tmp;
  TemporalMap map(0.05);
  for (int i = 0; i < 2; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(static_cast<uint64_t>(30 + i), 8));
  io::writeTemporalMap(tmp / "m.cmap", map, {});
  const std::string m = (tmp / "m.cmap").string(), t = (tmp / "t").string();
  const test::CommandResult bad_size = runCommand(cli() + " tile " + m + " -o " + t + " --tile-size 0.3");
  EXPECT_NE(bad_size.exit_code, 0);
  EXPECT_NE(bad_size.err.find("power-of-two"), std::string::npos) << bad_size.err;
  EXPECT_FALSE(fs::exists(t));
  ASSERT_EQ(runCommand(cli() + " tile " + m + " -o " + t + " --tile-size 0.2").exit_code, 0);

  const test::CommandResult mixed = runCommand(cli() + " diff " + t + "@1000 " + m + "@2000 -o " + (tmp / "d.cmap").string());
  EXPECT_NE(mixed.exit_code, 0);
  EXPECT_NE(mixed.err.find("tiled map"), std::string::npos) << mixed.err;
  const test::CommandResult box = runCommand(cli() + " snapshot " + m + " --at 2000 --box 0,0,0,1,1,1 -o " +
                                             (tmp / "s.cmap").string());
  EXPECT_NE(box.exit_code, 0);
  EXPECT_NE(box.err.find("box"), std::string::npos) << box.err;

  const io::TileIndex index = io::readTileIndex(t);
  fs::remove(fs::path(t) / index.tiles.front().file);
  const test::CommandResult missing = runCommand(cli() + " snapshot " + t + " --at 2000 -o " + (tmp / "s.cmap").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("tile file missing"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  EXPECT_FALSE(fs::exists(tmp / "s.cmap"));
}

}  // namespace
}  // namespace chronomap
