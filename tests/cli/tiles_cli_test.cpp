// Tiled maps on the command line: tile, untile, and snapshot / history / diff given a folder.

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "chronomap/store/cmap.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/store/tiled_file.h"
#include "builders.h"
#include "test_support.h"
#include "window_compare.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;
using test::cli;
using test::runCommand;

TEST(TilesCli, TiledFolderAnswersAsTheMap) {
  test::TempDir tmp;
  TemporalMap map(0.05);
  for (int i = 0; i < 3; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(static_cast<uint64_t>(20 + i), 12));
  writeTemporalMap(tmp / "m.cmap", map, {});
  const std::string m = (tmp / "m.cmap").string(), t = (tmp / "t").string();

  const test::CommandResult tiled = runCommand(cli() + " tile " + m + " -o " + t + " --tile-size 0.2 --json");
  ASSERT_EQ(tiled.exit_code, 0) << tiled.err;
  const nlohmann::json tj = nlohmann::json::parse(tiled.out);
  EXPECT_EQ(tj["tile_level"], 2);
  EXPECT_EQ(tj["tiles"], 27);  // 12 voxels per axis from a tile corner: 3 x 3 x 3 tiles of 4

  // The whole snapshot, from the folder and from the file.
  ASSERT_EQ(runCommand(cli() + " snapshot " + t + " --at 2500 -o " + (tmp / "a.cmap").string()).exit_code, 0);
  ASSERT_EQ(runCommand(cli() + " snapshot " + m + " --at 2500 -o " + (tmp / "b.cmap").string()).exit_code, 0);
  EXPECT_TRUE(readSessionMap(tmp / "a.cmap") == readSessionMap(tmp / "b.cmap"));

  // With windows of one session each: every earlier time read from them, the same answer.
  const std::string t1 = (tmp / "t1").string();
  const test::CommandResult windowed = runCommand(cli() + " tile " + m + " -o " + t1 + " --tile-size 0.2 --tile-windows 1 --json");
  ASSERT_EQ(windowed.exit_code, 0) << windowed.err;
  EXPECT_EQ(nlohmann::json::parse(windowed.out)["windows"], 27 * 3);
  EXPECT_EQ(tj["windows"], 0);
  EXPECT_EQ(readTileIndex(t1).window_sessions, 1u);
  EXPECT_EQ(readTileIndex(t1).tiles[0].windows.size(), 3u);
  EXPECT_EQ(readTileIndex(t).window_sessions, 0u);  // 3 sessions: no whole run of the default's
  ASSERT_EQ(runCommand(cli() + " snapshot " + t1 + " --at 2500 -o " + (tmp / "a1.cmap").string()).exit_code, 0);
  EXPECT_TRUE(readSessionMap(tmp / "a1.cmap") == readSessionMap(tmp / "b.cmap"));

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
  EXPECT_TRUE(readDiffMap(tmp / "d1.cmap") == readDiffMap(tmp / "d2.cmap"));
  EXPECT_FALSE(readDiffMap(tmp / "d1.cmap").empty());

  // Joined back: the same map.
  ASSERT_EQ(runCommand(cli() + " untile " + t + " -o " + (tmp / "back.cmap").string()).exit_code, 0);
  EXPECT_TRUE(readTemporalMap(tmp / "back.cmap") == readTemporalMap(tmp / "m.cmap"));
}

TEST(TilesCli, BadInputGivesOneLine) {
  test::TempDir tmp;
  TemporalMap map(0.05);
  for (int i = 0; i < 2; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(static_cast<uint64_t>(30 + i), 8));
  writeTemporalMap(tmp / "m.cmap", map, {});
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

  // The last session's snapshot reads the tiles' latest states, an earlier one their histories.
  const TileIndex index = readTileIndex(t);
  ASSERT_TRUE(index.tiles.front().latest.has_value());
  fs::remove(fs::path(t) / index.tiles.front().latest->file);
  const test::CommandResult no_latest =
      runCommand(cli() + " snapshot " + t + " --at 2000 -o " + (tmp / "s.cmap").string());
  EXPECT_NE(no_latest.exit_code, 0);
  EXPECT_NE(no_latest.err.find("latest state file missing"), std::string::npos) << no_latest.err;
  EXPECT_EQ(std::count(no_latest.err.begin(), no_latest.err.end(), '\n'), 1) << no_latest.err;
  fs::remove(fs::path(t) / index.tiles.front().file);
  const test::CommandResult missing =
      runCommand(cli() + " snapshot " + t + " --at 1000 -o " + (tmp / "s.cmap").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("tile file missing"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  EXPECT_FALSE(fs::exists(tmp / "s.cmap"));
}

/// The tiny scene's sessions (TUM folders), 4 of them.
std::vector<std::string> tinySessions(const test::TempDir& tmp) {
  const test::CommandResult r = runCommand(cli() + " simulate --preset tiny --sessions 4 --resolution-scale 0.1 -o " +
                                           (tmp / "sim").string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> out;
  for (int i = 0; i < 4; ++i) out.push_back(" " + (tmp / "sim" / ("session_0" + std::to_string(i))).string());
  return out;
}

/// `untile` of `folder` into `out`, from a copy named "m" (untile records the folder's name).
std::vector<uint8_t> untiled(const test::TempDir& tmp, const fs::path& folder) {
  fs::remove_all(tmp / "m");
  fs::copy(folder, tmp / "m", fs::copy_options::recursive);
  const test::CommandResult r = runCommand("cd " + tmp.path().string() + " && " + cli() + " untile m -o u.cmap");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return test::bytesOf(tmp / "u.cmap");
}

TEST(TilesCli, StreamingBuildGivesTheWholeBuildTiled) {
  test::TempDir tmp;
  const std::vector<std::string> s = tinySessions(tmp);
  const std::string w = (tmp / "w.cmap").string(), wt = (tmp / "wt").string(), st = (tmp / "st").string();
  ASSERT_EQ(runCommand(cli() + " build " + w + s[0] + s[1]).exit_code, 0);
  ASSERT_EQ(runCommand(cli() + " build " + w + s[2] + s[3]).exit_code, 0);
  ASSERT_EQ(runCommand(cli() + " tile " + w + " -o " + wt + " --tile-size 1.6").exit_code, 0);
  const std::vector<uint8_t> expected = untiled(tmp, wt);

  // The same batches streamed (given out of order), the second with a tiny budget.
  const test::CommandResult first =
      runCommand(cli() + " build " + st + s[1] + s[0] + " --tiles --tile-size 1.6 --json");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_TRUE(nlohmann::json::parse(first.out)["created"].get<bool>());
  const std::vector<uint8_t> half = untiled(tmp, st);
  // (With windows of 2 sessions: each tile then gets those of sessions 1-2 and 3-4.)
  const test::CommandResult second =
      runCommand(cli() + " build " + st + s[2] + s[3] + " --memory-limit 0.001 --tile-windows 2 --json");
  ASSERT_EQ(second.exit_code, 0) << second.err;
  const nlohmann::json j = nlohmann::json::parse(second.out);
  EXPECT_EQ(j["sessions"], 4);
  EXPECT_GT(j["spills"].get<size_t>(), 0u);
  EXPECT_LE(j["peak_parts_bytes"].get<size_t>(), 1073742u);
  EXPECT_TRUE(untiled(tmp, st) == expected);
  const TileIndex index = readTileIndex(st);
  EXPECT_EQ(index.window_sessions, 2u);
  size_t windows = 0;
  for (const TileEntry& e : index.tiles) windows += e.windows.size();
  EXPECT_EQ(j["windows_written"].get<size_t>(), windows);
  EXPECT_GT(windows, index.tiles.size());
  // The earlier sessions' snapshots, read from the windows, are the whole map's.
  for (size_t k = 0; k < 3; ++k) {
    const std::string at = nlohmann::json(index.top.sessions()[k].time_s).dump();
    ASSERT_EQ(runCommand(cli() + " snapshot " + st + " --at " + at + " -o " + (tmp / "a.cmap").string()).exit_code, 0);
    ASSERT_EQ(runCommand(cli() + " snapshot " + w + " --at " + at + " -o " + (tmp / "b.cmap").string()).exit_code, 0);
    EXPECT_TRUE(readSessionMap(tmp / "a.cmap") == readSessionMap(tmp / "b.cmap")) << "session " << k + 1;
  }
  // Tiles kept as windows of one session (--windowed-tiles): streamed in the same batches, or cut
  // from the whole map by `tile`, they join to the same map.
  const std::string sw = (tmp / "sw").string(), tw = (tmp / "tw").string();
  ASSERT_EQ(runCommand(cli() + " build " + sw + s[1] + s[0] + " --tiles --tile-size 1.6 --tile-windows 1 --windowed-tiles")
                .exit_code,
            0);
  const test::CommandResult windowed = runCommand(cli() + " build " + sw + s[2] + s[3] + " --json");
  ASSERT_EQ(windowed.exit_code, 0) << windowed.err;
  ASSERT_TRUE(readTileIndex(sw).windowed);
  // (The sessions' node counts are the growth of each tile's open window: the map's history is
  // the same, its records' counts of the sessions windows closed before differ.)
  untiled(tmp, sw);
  EXPECT_TRUE(test::sameHistory(readTemporalMap(tmp / "u.cmap"), readTemporalMap(w)));
  ASSERT_EQ(runCommand(cli() + " tile " + w + " -o " + tw + " --tile-size 1.6 --tile-windows 1 --windowed-tiles").exit_code, 0);
  ASSERT_TRUE(readTileIndex(tw).windowed);
  EXPECT_TRUE(untiled(tmp, tw) == expected);
  // An existing folder keeps its layout, and says so.
  const std::string kl = (tmp / "kl").string();
  ASSERT_EQ(runCommand(cli() + " build " + kl + s[0] + " --tiles --tile-size 1.6").exit_code, 0);
  const test::CommandResult kept_layout = runCommand(cli() + " build " + kl + s[1] + " --windowed-tiles");
  EXPECT_EQ(kept_layout.exit_code, 0) << kept_layout.err;
  EXPECT_NE(kept_layout.err.find("keeps its whole-history tiles"), std::string::npos) << kept_layout.err;
  EXPECT_FALSE(readTileIndex(kl).windowed);
  const test::CommandResult no_tiles_windowed = runCommand(cli() + " build " + (tmp / "x.cmap").string() + s[0] + " --windowed-tiles");
  EXPECT_EQ(no_tiles_windowed.exit_code, 2);
  EXPECT_NE(no_tiles_windowed.err.find("--windowed-tiles needs --tiles"), std::string::npos) << no_tiles_windowed.err;
  const test::CommandResult no_tiles = runCommand(cli() + " build " + (tmp / "x.cmap").string() + s[0] + " --tile-windows 2");
  EXPECT_EQ(no_tiles.exit_code, 2);
  EXPECT_NE(no_tiles.err.find("--tile-windows needs --tiles"), std::string::npos) << no_tiles.err;

  // Bad input leaves the tiled map as it was: an earlier session, re-alignment, another tile size.
  const std::vector<uint8_t>& before = expected;  // what st holds now
  const test::CommandResult earlier = runCommand(cli() + " build " + st + s[1]);
  EXPECT_EQ(earlier.exit_code, 2);
  EXPECT_NE(earlier.err.find("not after the tiled map's last session"), std::string::npos) << earlier.err;
  const test::CommandResult reg = runCommand(cli() + " build " + (tmp / "r").string() + s[0] + " --tiles --realign");
  EXPECT_EQ(reg.exit_code, 2);
  EXPECT_NE(reg.err.find("--realign cannot be used with --tiles"), std::string::npos) << reg.err;
  EXPECT_FALSE(fs::exists(tmp / "r"));
  EXPECT_EQ(runCommand(cli() + " build " + st + s[3] + " --tile-size 0.8").exit_code, 2);
  EXPECT_TRUE(untiled(tmp, st) == before);

  // Killed during an add: the folder reads as before the add or after it, never broken (the
  // library test fails an add at a chosen point; here the moment is the scheduler's).
  for (const char* after : {"0.25"}) {
    fs::remove_all(tmp / "k");
    ASSERT_EQ(runCommand(cli() + " build " + (tmp / "k").string() + s[0] + s[1] + " --tiles --tile-size 1.6").exit_code,
              0);
    runCommand("timeout -s KILL " + std::string(after) + " " + cli() + " build " + (tmp / "k").string() + s[2] + s[3]);
    const std::vector<uint8_t> now = untiled(tmp, tmp / "k");
    EXPECT_TRUE(now == half || now == expected) << "killed after " << after << " s";
  }
}

// Registration in the streaming build. The first run registers its recordings among themselves
// as the whole build registers them, so the tiles are the whole build's, cut; the JSON gives each
// session's correction, the whole build's. A later run registers against the stored sessions'
// consensus too (as `build MAP.cmap --register` registers against the 4D map's consensus), and
// every run sums its sessions into that consensus. One round of registration each (the
// properties do not depend on the rounds; three took over a minute under the sanitizers).
TEST(TilesCli, StreamingBuildRegistersAsTheWholeBuild) {
  test::TempDir tmp;
  const std::vector<std::string> s = tinySessions(tmp);
  const std::string w = (tmp / "w.cmap").string(), wt = (tmp / "wt").string(), st = (tmp / "st").string();
  const test::CommandResult whole = runCommand(cli() + " build " + w + s[0] + s[1] + s[2] + " --register --register-rounds 1 --json");
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  ASSERT_EQ(runCommand(cli() + " tile " + w + " -o " + wt + " --tile-size 1.6").exit_code, 0);
  const std::vector<uint8_t> expected = untiled(tmp, wt);

  const test::CommandResult night =
      runCommand(cli() + " build " + st + s[2] + s[0] + s[1] + " --tiles --tile-size 1.6 --register --register-rounds 1 --json");
  ASSERT_EQ(night.exit_code, 0) << night.err;
  const nlohmann::json first = nlohmann::json::parse(night.out);
  const nlohmann::json added = first["added"];
  const nlohmann::json built = nlohmann::json::parse(whole.out)["added"];
  ASSERT_EQ(added.size(), 3u);
  ASSERT_EQ(built.size(), 3u);
  double moved = 0.0;
  for (size_t i = 0; i < 3; ++i) {
    ASSERT_TRUE(added[i].contains("registration_m")) << added[i].dump();
    EXPECT_EQ(added[i]["registration_m"], built[i]["registration_m"]) << i;
    EXPECT_EQ(added[i]["registration_deg"], built[i]["registration_deg"]) << i;
    for (const auto& v : added[i]["registration_m"]) moved += std::abs(v.get<double>());
  }
  EXPECT_GT(moved, 0.0);  // the tiny scene's recorded poses are off: registration moved something
  EXPECT_TRUE(untiled(tmp, st) == expected);
  EXPECT_EQ(first["consensus_sessions"], 3);
  EXPECT_TRUE(first["warnings"].empty()) << first["warnings"].dump();
  // Both report the registration that ran, the same: plain --register, one round.
  ASSERT_TRUE(first.contains("registration")) << night.out;
  EXPECT_EQ(first["registration"], nlohmann::json::parse(whole.out)["registration"]);
  EXPECT_EQ(first["registration"]["preset"], "none");
  EXPECT_EQ(first["registration"]["rounds"], 1);

  // The next night: against the stored sessions (the folder's consensus of them; a .cmap's, its
  // 4D map's consensus), where the same recording registered alone has nothing to move towards.
  const std::string fresh = (tmp / "fresh.cmap").string();
  const auto movedBy = [](const std::string& out) {
    const nlohmann::json report = nlohmann::json::parse(out);  // held: the loop reads into it
    double sum = 0.0;
    for (const auto& v : report["added"][0]["registration_m"]) sum += std::abs(v.get<double>());
    return sum;
  };
  const test::CommandResult alone = runCommand(cli() + " build " + fresh + s[3] + " --register --register-rounds 1 --json");
  ASSERT_EQ(alone.exit_code, 0) << alone.err;
  EXPECT_LT(movedBy(alone.out), 1e-6);
  const test::CommandResult added_to_map = runCommand(cli() + " build " + w + s[3] + " --register --register-rounds 1 --json");
  ASSERT_EQ(added_to_map.exit_code, 0) << added_to_map.err;
  EXPECT_GT(movedBy(added_to_map.out), 1e-3) << added_to_map.out;
  const test::CommandResult next = runCommand(cli() + " build " + st + s[3] + " --register --register-rounds 1 --json");
  ASSERT_EQ(next.exit_code, 0) << next.err;
  EXPECT_EQ(nlohmann::json::parse(next.out)["consensus_sessions"], 4);
  EXPECT_GT(movedBy(next.out), 1e-3) << next.out;
  const std::vector<uint8_t> after_night = untiled(tmp, st);
  // An earlier recording is refused before registration, the folder unchanged.
  const test::CommandResult earlier = runCommand(cli() + " build " + st + s[0] + s[3] + " --register --register-rounds 1");
  EXPECT_EQ(earlier.exit_code, 2);
  EXPECT_NE(earlier.err.find("not after the tiled map's last session"), std::string::npos) << earlier.err;
  EXPECT_EQ(earlier.err.find("registering"), std::string::npos) << earlier.err;
  EXPECT_TRUE(untiled(tmp, st) == after_night);

  // A folder built without registration keeps no consensus: a registered run computes it from the
  // stored sessions' histories, says so, and keeps it.
  const std::string plain = (tmp / "plain").string();
  const test::CommandResult unregistered = runCommand(cli() + " build " + plain + s[0] + s[1] + " --tiles --tile-size 1.6 --json");
  ASSERT_EQ(unregistered.exit_code, 0) << unregistered.err;
  EXPECT_EQ(nlohmann::json::parse(unregistered.out)["consensus_sessions"], 0);
  const test::CommandResult started = runCommand(cli() + " build " + plain + s[2] + " --register --register-rounds 1");
  ASSERT_EQ(started.exit_code, 0) << started.err;
  EXPECT_NE(started.err.find("kept no consensus of its 2 stored session(s)"), std::string::npos) << started.err;
  EXPECT_NE(started.out.find("the registration's consensus holds 3 session(s)"), std::string::npos) << started.out;
}

TEST(TilesCli, AddToATiledFolderStreamsTheSession) {
  test::TempDir tmp;
  TemporalMap map(0.05);
  for (int i = 0; i < 2; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(static_cast<uint64_t>(40 + i), 12));
  writeTemporalMap(tmp / "m.cmap", map, {});
  writeSessionMap(tmp / "s.cmap", test::randomSessionMap(42, 12), {{"recorded_at", 3000.0}});
  const std::string m = (tmp / "m.cmap").string(), s = (tmp / "s.cmap").string();
  ASSERT_EQ(runCommand(cli() + " tile " + m + " -o " + (tmp / "t").string() + " --tile-size 0.2").exit_code, 0);
  // The whole map: add, then tile; the tiled folder: add (streamed).
  ASSERT_EQ(runCommand(cli() + " add " + m + " " + s).exit_code, 0);
  ASSERT_EQ(runCommand(cli() + " tile " + m + " -o " + (tmp / "w").string() + " --tile-size 0.2").exit_code, 0);
  fs::copy(tmp / "t", tmp / "t1", fs::copy_options::recursive);
  const test::CommandResult r = runCommand(cli() + " add " + (tmp / "t").string() + " " + s + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["sessions"], 3);
  EXPECT_TRUE(untiled(tmp, tmp / "t") == untiled(tmp, tmp / "w"));
  // On one thread: the same files, every one of them.
  const test::CommandResult one = runCommand(cli() + " add " + (tmp / "t1").string() + " " + s + " --threads 1");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  for (const auto& f : fs::recursive_directory_iterator(tmp / "t")) {
    if (f.is_regular_file()) {
      EXPECT_TRUE(test::bytesOf(f.path()) == test::bytesOf(tmp / "t1" / fs::relative(f.path(), tmp / "t")))
          << f.path();
    }
  }
  // Options that do not apply: refused, the folder unchanged.
  const std::vector<uint8_t> before = untiled(tmp, tmp / "t");
  EXPECT_EQ(runCommand(cli() + " add " + (tmp / "t").string() + " " + s + " --time 4000 --replace").exit_code, 2);
  EXPECT_EQ(runCommand(cli() + " add " + (tmp / "t").string() + " " + s + " --time 2500").exit_code, 2);
  EXPECT_EQ(runCommand(cli() + " add " + m + " " + s + " --time 4000 --memory-limit 1").exit_code, 2);
  const test::CommandResult threads = runCommand(cli() + " add " + m + " " + s + " --time 4000 --threads 2");
  EXPECT_EQ(threads.exit_code, 2);
  EXPECT_NE(threads.err.find("--threads applies to a tiled map folder only"), std::string::npos) << threads.err;
  EXPECT_TRUE(untiled(tmp, tmp / "t") == before);
}

}  // namespace
}  // namespace chronomap
