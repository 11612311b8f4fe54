// The 4D map on the command line: add, build, snapshot, history, changes, stats; bad input;
// and a harness that kills `chronomap add` at random moments.

#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/octree/session_map.h"
#include "builders.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::bytesOf;
using test::cli;

/// The path of session file i ("s0.cmap").
fs::path sessionFile(const test::TempDir& dir, int i) {
  std::string name("s");
  name.append(std::to_string(i)).append(".cmap");
  return dir / name;
}

/// Three session files s0..s2 in `dir`.
void writeSessions(const test::TempDir& dir, int side = 16) {
  for (int i = 0; i < 3; ++i) {
    writeSessionMap(sessionFile(dir, i),
                        test::randomSessionMap(static_cast<uint64_t>(10 + i), side), {});
  }
}

TEST(TemporalCli, PredictFitsSavesAndReusesTheModel) {
  test::TempDir tmp;
  // A voxel occupied in every other session (at 100, 300, 500 ... s), free between.
  const std::string map = (tmp / "m.cmap").string();
  for (int i = 0; i < 8; ++i) {
    SessionMap s(0.05);
    s.add(test::at(0, 0, 0), test::occupiedVoxel(Rgb{200, 10, 10}));
    s.add(test::at(5, 5, 5), i % 2 == 0 ? test::occupiedVoxel(Rgb{}) : test::freeVoxel());
    writeSessionMap(sessionFile(tmp, i), s, {});
    ASSERT_EQ(test::runCommand(cli() + " add " + map + " " + sessionFile(tmp, i).string() + " --time " +
                               std::to_string(100 * (i + 1)))
                  .exit_code,
              0);
  }
  const std::string rhythm = (tmp / "m.rhythm").string();
  auto r = test::runCommand(cli() + " predict " + map + " --at 900 --model mean -o " + (tmp / "p.cmap").string() +
                            " --save-rhythm " + rhythm + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["modelled_voxels"], 1);
  EXPECT_EQ(j["learning_sessions"], 8);
  EXPECT_EQ(j["model"], "mean");
  // The mean model: occupied in half the sessions (the file keeps the probability to within
  // what its quantised lengths allow, kLengthRelativeError / e).
  const double stored_p = kLengthRelativeError / std::exp(1.0) + 1e-6;
  const SessionMap p = readSessionMap(tmp / "p.cmap");
  EXPECT_NEAR(p.find(test::at(5, 5, 5))->probability(), 0.5, stored_p);
  EXPECT_EQ(p.stateOf(test::at(0, 0, 0)), VoxelState::Occupied);
  // The saved model gives the same prediction without refitting, and learning only from the
  // first three sessions gives two occupied of three.
  r = test::runCommand(cli() + " predict " + map + " --at 900 --model mean --rhythm " + rhythm + " -o " +
                       (tmp / "q.cmap").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(readSessionMap(tmp / "q.cmap"), p);
  r = test::runCommand(cli() + " predict " + map + " --at 900 --model mean --learn-to 300 -o " + (tmp / "e.cmap").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NEAR(readSessionMap(tmp / "e.cmap").find(test::at(5, 5, 5))->probability(), 2.0 / 3.0, stored_p);
  // Bad input: one line naming what is wrong; nothing written.
  const std::pair<std::string, std::string> bad[] = {
      {" --at 900 -o " + (tmp / "x.txt").string(), "must end in"},
      {" --at soon -o " + (tmp / "x.png").string(), "neither ISO-8601"},
      {" --at 900 --model fourier -o " + (tmp / "x.png").string(), "unknown model"},
      {" --at 900 --rhythm " + map + " -o " + (tmp / "x.png").string(), "not a chronomap rhythm model"},
      {" --at 900 --rhythm " + rhythm + " --learn-to 300 -o " + (tmp / "x.png").string(), "takes no"},
      {" --at 900 --learn-from 5000 -o " + (tmp / "x.png").string(), "no session"},
      {" --at 900 -o " + map, "input"},
  };
  for (const auto& [args, message] : bad) {
    r = test::runCommand(cli() + " predict " + map + args);
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_FALSE(fs::exists(tmp / "x.png"));
  std::vector<uint8_t> truncated = readFileBytes(rhythm);
  truncated.resize(truncated.size() - 5);
  writeFileAtomic(tmp / "t.rhythm", truncated);
  r = test::runCommand(cli() + " predict " + map + " --at 900 --rhythm " + (tmp / "t.rhythm").string() + " -o " +
                       (tmp / "x.png").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("t.rhythm"), std::string::npos) << r.err;
}

TEST(TemporalCli, CostmapWritesMapServerFiles) {
  test::TempDir tmp;
  // A floor area seen free with a wall voxel column, in two sessions; a box at (5, 5) in one.
  const std::string map = (tmp / "m.cmap").string();
  for (int i = 0; i < 2; ++i) {
    SessionMap s(0.05);
    for (int x = 0; x < 10; ++x) {
      for (int y = 0; y < 10; ++y) {
        const bool wall = x == 0, box = i == 1 && x == 5 && y == 5;
        s.add(VoxelKey{static_cast<uint16_t>(32768 + x), static_cast<uint16_t>(32768 + y), 32770},
              wall || box ? test::occupiedVoxel(Rgb{}) : test::freeVoxel());
      }
    }
    writeSessionMap(sessionFile(tmp, i), s, {});
    ASSERT_EQ(test::runCommand(cli() + " add " + map + " " + sessionFile(tmp, i).string() + " --time " +
                               std::to_string(100 * (i + 1)))
                  .exit_code,
              0);
  }
  const auto r = test::runCommand(cli() + " costmap " + map + " --at 200 --robot-radius 0 --model latest -o " +
                                  (tmp / "cost.yaml").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["width"], 10);
  EXPECT_EQ(j["height"], 10);
  EXPECT_EQ(j["blocked"], 11);  // the wall's ten cells and the box
  EXPECT_NE(readTextFile(tmp / "cost.yaml").find("image: cost.pgm"), std::string::npos);
  EXPECT_NE(readTextFile(tmp / "cost.yaml").find("mode: raw"), std::string::npos);
  const std::vector<uint8_t> pgm = readFileBytes(tmp / "cost.pgm");
  EXPECT_EQ(pgm.size(), std::string("P5\n10 10\n255\n").size() + 100);
  EXPECT_TRUE(fs::exists(tmp / "cost.png"));
  // Bad input: one line, nothing written.
  const std::pair<std::string, std::string> bad[] = {
      {" --at 200 -o " + (tmp / "c.pgm").string(), "must end in .yaml"},
      {" --at 200 --z-min 1 --z-max 0.5 -o " + (tmp / "c.yaml").string(), "--z-max above --z-min"},
      {" --at 200 --z-min 5 --z-max 6 -o " + (tmp / "c.yaml").string(), "nothing is known"},
      {" --at 200 --robot-radius -1 -o " + (tmp / "c.yaml").string(), "--robot-radius"},
      {" --at 200 --change-weight 2 -o " + (tmp / "c.yaml").string(), "--change-weight"},
  };
  for (const auto& [args, message] : bad) {
    const auto b = test::runCommand(cli() + " costmap " + map + args);
    EXPECT_NE(b.exit_code, 0) << args;
    EXPECT_NE(b.err.find(message), std::string::npos) << args << ": " << b.err;
  }
  EXPECT_FALSE(fs::exists(tmp / "c.yaml"));
  EXPECT_FALSE(fs::exists(tmp / "c.pgm"));
}

TEST(TemporalCli, CostmapRadiusDoesNotCostMemory) {
  // `--robot-radius 100` on a 1 cm map: inflation stamped a disk of (2 x 10^4)^2 offsets, 3.2 GB,
  // and ran out of memory. Under the shell's 2 GiB address-space limit (not under sanitizers) it
  // now finishes: every cell of the 10 x 10 floor but the one wall voxel is blocked.
  test::TempDir tmp;
  const std::string map = (tmp / "m.cmap").string();
  SessionMap s(0.01);
  for (int x = 0; x < 10; ++x) {
    for (int y = 0; y < 10; ++y) {
      s.add(VoxelKey{static_cast<uint16_t>(32768 + x), static_cast<uint16_t>(32768 + y), 32778},
            x == 4 && y == 4 ? test::occupiedVoxel(Rgb{}) : test::freeVoxel());
    }
  }
  writeSessionMap(sessionFile(tmp, 0), s, {});
  ASSERT_EQ(test::runCommand(cli() + " add " + map + " " + sessionFile(tmp, 0).string() + " --time 100").exit_code, 0);
  const std::string limit = test::memoryLimitsApply() ? "ulimit -v 2097152; " : "";
  const auto r = test::runCommand(limit + cli() + " costmap " + map + " --at 100 --robot-radius 100 --model latest -o " +
                                  (tmp / "cost.yaml").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["width"], 10);
  EXPECT_EQ(j["blocked"], 100);
}

TEST(TemporalCli, AddRealignMovesAShiftedSessionBack) {
  test::TempDir tmp;
  for (int i = 0; i < 3; ++i) writeSessionMap(sessionFile(tmp, i), test::wallSession(10, 0), {});
  writeSessionMap(tmp / "shifted.cmap", test::wallSession(11, 0), {});
  int64_t added[2] = {0, 0};
  for (int realign = 0; realign < 2; ++realign) {
    const std::string map = (tmp / ("m" + std::to_string(realign) + ".cmap")).string();
    for (int i = 0; i < 3; ++i) {
      ASSERT_EQ(test::runCommand(cli() + " add " + map + " " + sessionFile(tmp, i).string() + " --time " +
                                 std::to_string(100 * (i + 1)))
                    .exit_code,
                0);
    }
    const auto r = test::runCommand(cli() + " add " + map + " " + (tmp / "shifted.cmap").string() + " --time 400 --json" +
                                    (realign ? " --realign" : ""));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    added[realign] = j["nodes_added"].get<int64_t>();
    if (realign) {
      EXPECT_EQ(j["realigned_voxels"], 256);
    } else {
      EXPECT_FALSE(j.contains("realigned_voxels"));
    }
  }
  EXPECT_GE(added[0], 512);  // every wall voxel changed twice: vanished here, appeared behind
  EXPECT_LT(added[1], 64);   // re-aligned: the wall is where it was
  // Bad settings are refused before anything is written.
  const std::string map = (tmp / "m1.cmap").string();
  const auto before = bytesOf(map);
  for (const char* bad : {"--realign-alpha -1", "--realign-max-distance 20", "--realign-move sideways"}) {
    const auto r = test::runCommand(cli() + " add " + map + " " + (tmp / "shifted.cmap").string() +
                                    " --time 500 --realign " + bad);
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_FALSE(r.err.empty());
  }
  EXPECT_EQ(bytesOf(map), before);
}

TEST(TemporalCli, HelpForEveryCommand) {
  for (const char* cmd : {"add", "build", "snapshot", "history", "changes", "stats"}) {
    const auto r = test::runCommand(cli() + " " + cmd + " --help");
    EXPECT_EQ(r.exit_code, 0) << cmd;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << cmd;
  }
}

TEST(TemporalCli, AddSnapshotHistoryChangesStats) {
  test::TempDir tmp;
  writeSessions(tmp);
  const std::string map = (tmp / "m.cmap").string();
  const char* times[] = {"2012-03-01T10:00:00Z", "2012-03-03T10:00:00Z", "2012-03-02T10:00:00Z"};
  for (int i = 0; i < 3; ++i) {
    const auto r = test::runCommand(cli() + " add " + map + " " + sessionFile(tmp, i).string() +
                                    " --time " + times[i] + " --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["sessions"], i + 1);
    EXPECT_EQ(j["out_of_order"], i == 2);
  }
  // The map on disk equals the library's map built from the same sessions.
  TemporalMap expected(0.05);
  for (int i = 0; i < 3; ++i) {
    expected.add(parseTime(times[i]), readSessionMap(sessionFile(tmp, i)));
  }
  const TemporalMap onDisk = readTemporalMap(map);
  for (double t : expected.times()) {
    const SessionMap a = onDisk.snapshot(t), b = expected.snapshot(t);
    EXPECT_EQ(a.counts().occupied_voxels, b.counts().occupied_voxels);
    EXPECT_EQ(a.counts().free_voxels, b.counts().free_voxels);
  }

  // snapshot to a session map equals the library snapshot.
  auto r = test::runCommand(cli() + " snapshot " + map + " --at 2012-03-02T12:00:00Z -o " + (tmp / "snap.cmap").string() +
                            " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const SessionMap snap = readSessionMap(tmp / "snap.cmap");
  const SessionMap lib = expected.snapshot(parseTime("2012-03-02T12:00:00Z"));
  EXPECT_EQ(snap.counts().occupied_voxels, lib.counts().occupied_voxels);
  EXPECT_EQ(nlohmann::json::parse(r.out)["occupied"], lib.counts().occupied_voxels);
  for (const char* ext : {"ply", "ot", "png"}) {
    const fs::path out = tmp / (std::string("snap.") + ext);
    r = test::runCommand(cli() + " snapshot " + map + " --at 1330682400 -o " + out.string());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_GT(fs::file_size(out), 100u);
  }
  r = test::runCommand(cli() + " snapshot " + map + " --at 2000-01-01 -o " + (tmp / "early.ply").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("no session at or before"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "early.ply"));

  // history of a voxel: the library's entries.
  r = test::runCommand(cli() + " history " + map + " --point 0.01,0.01,0.01 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto h = nlohmann::json::parse(r.out);
  const auto libHistory = expected.history(VoxelKey{kKeyOrigin, kKeyOrigin, kKeyOrigin});
  ASSERT_EQ(h["entries"].size(), libHistory.size());
  for (size_t i = 0; i < libHistory.size(); ++i) {
    EXPECT_EQ(h["entries"][i]["state"], toString(libHistory[i].counters.state()));
    EXPECT_EQ(h["entries"][i]["time_s"].get<double>(), libHistory[i].time_s);
  }
  r = test::runCommand(cli() + " history " + map + " --point 0.01,0.01,0.01");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("2012-03-01T10:00:00Z"), std::string::npos) << r.out;

  // changes: the number of voxels with at least one change.
  uint64_t changedVoxels = 0;
  expected.forEachChangeCount(-1e300, 1e300, [&](const VoxelKey&, int level, uint32_t) {
    changedVoxels += uint64_t{1} << (3 * level);
  });
  ASSERT_GT(changedVoxels, 0u);
  r = test::runCommand(cli() + " changes " + map + " --min 1 -o " + (tmp / "changes.ply").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["voxels"].get<uint64_t>(), changedVoxels);
  EXPECT_TRUE(fs::exists(tmp / "changes.ply"));

  // stats --json with the contract's keys, and the storage plot.
  r = test::runCommand(cli() + " stats " + map + " --json --plot " + (tmp / "storage.png").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto s = nlohmann::json::parse(r.out);
  for (const char* key : {"kind", "resolution_m", "sessions", "times", "nodes", "bytes", "nodes_separate"}) {
    EXPECT_TRUE(s.contains(key)) << key;
  }
  EXPECT_EQ(s["kind"], "4d");
  EXPECT_EQ(s["sessions"], 3);
  EXPECT_EQ(s["times"][0], "2012-03-01T10:00:00Z");
  EXPECT_EQ(s["times"][1], "2012-03-02T10:00:00Z");
  EXPECT_LT(s["nodes"].get<uint64_t>(), s["nodes_separate"].get<uint64_t>());
  EXPECT_GT(fs::file_size(tmp / "storage.png"), 1000u);
}

// --min-free-length and --min-hits (the evidence rule) go into a new map's criterion; the map
// reads as the library's built with it (every snapshot, the node count); a bad value exits 2 and
// writes nothing.
TEST(TemporalCli, TheEvidenceRuleFlagsMakeTheMapsCriterion) {
  test::TempDir tmp;
  writeSessions(tmp);
  const std::string map = (tmp / "e.cmap").string();
  const char* times[] = {"2012-03-01T10:00:00Z", "2012-03-02T10:00:00Z"};
  ChangeCriterion rule;
  rule.min_free_length_m = 0.02;
  rule.min_hits = 3;
  TemporalMap expected(0.05, rule);
  for (int i = 0; i < 2; ++i) {
    const auto r = test::runCommand(cli() + " add " + map + " " + sessionFile(tmp, i).string() + " --time " +
                                    times[i] + " --min-free-length 0.02 --min-hits 3");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expected.add(parseTime(times[i]), readSessionMap(sessionFile(tmp, i)));
  }
  const TemporalMap onDisk = readTemporalMap(map);
  EXPECT_TRUE(onDisk.criterion() == rule);
  for (const double t : expected.times()) EXPECT_TRUE(onDisk.snapshot(t) == asStored(expected).snapshot(t)) << t;
  EXPECT_EQ(onDisk.counts().nodes(), asStored(expected).counts().nodes());
  const auto bad = test::runCommand(cli() + " add " + (tmp / "bad.cmap").string() + " " + sessionFile(tmp, 0).string() +
                                    " --time " + times[0] + " --min-free-length -1");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("minimum free length"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(tmp / "bad.cmap"));
}

// export draws what a user has: a 4D map as last observed (at its last session, or --at), as
// chronomap snapshot writes it, and messages name the map kind "4D".
TEST(TemporalCli, ExportOfA4DMapWritesItsLatestStateOrTheOneAt) {
  test::TempDir tmp;
  writeSessions(tmp);
  const std::string map = (tmp / "m.cmap").string();
  const char* times[] = {"2012-03-01T10:00:00Z", "2012-03-02T10:00:00Z", "2012-03-03T10:00:00Z"};
  TemporalMap expected(0.05);
  for (int i = 0; i < 3; ++i) expected.add(parseTime(times[i]), readSessionMap(sessionFile(tmp, i)));
  writeTemporalMap(map, expected, {});
  for (const char* ext : {".ply", ".ot", ".png"}) {
    const fs::path latest = tmp / (std::string("latest") + ext), snap = tmp / (std::string("snap") + ext);
    auto r = test::runCommand(cli() + " export " + map + " -o " + latest.string() + " --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["time"], times[2]) << ext;
    r = test::runCommand(cli() + " snapshot " + map + " --at " + times[2] + " -o " + snap.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(bytesOf(latest), bytesOf(snap)) << ext;  // one answer: the snapshot's
  }
  const SessionMap second = expected.snapshot(parseTime("2012-03-02T12:00:00Z"));
  auto r = test::runCommand(cli() + " export " + map + " -o " + (tmp / "second.ply").string() +
                            " --at 2012-03-02T12:00:00Z");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("the 4D map as last observed at 2012-03-02T12:00:00Z"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(" + std::to_string(second.counts().occupied_voxels) + " occupied voxel centres)"),
            std::string::npos) << r.out;
  // A time before the first session, --at on a session map or for a tour: refused, nothing written.
  r = test::runCommand(cli() + " export " + map + " -o " + (tmp / "early.ply").string() + " --at 2000-01-01");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("no session at or before"), std::string::npos) << r.err;
  r = test::runCommand(cli() + " export " + sessionFile(tmp, 0).string() + " -o " + (tmp / "s.ply").string() +
                       " --at 2012-03-01");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("is a session map: it has one time"), std::string::npos) << r.err;
  r = test::runCommand(cli() + " export " + map + " -o " + (tmp / "t.html").string() + " --at 2012-03-01");
  EXPECT_EQ(r.exit_code, 2);
  for (const char* name : {"early.ply", "s.ply", "t.html"}) EXPECT_FALSE(fs::exists(tmp / name)) << name;
  // "4D" in what people read; the JSON's kind stays the file's own name.
  r = test::runCommand(cli() + " stats " + map);
  EXPECT_NE(r.out.find(": 4D map, format version"), std::string::npos) << r.out;
  r = test::runCommand(cli() + " add " + (tmp / "other.cmap").string() + " " + map + " --time 2012-03-04");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("holds a 4D map, not a session map (one time of it: chronomap snapshot"), std::string::npos)
      << r.err;
}

TEST(TemporalCli, BadInputChangesNothing) {
  test::TempDir tmp;
  writeSessions(tmp);
  const std::string map = (tmp / "m.cmap").string();
  ASSERT_EQ(test::runCommand(cli() + " add " + map + " " + (tmp / "s0.cmap").string() + " --time 100").exit_code, 0);
  const auto before = bytesOf(map);
  struct Case {
    std::string args;
    int code;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"add " + map + " " + (tmp / "s1.cmap").string() + " --time 100", 2, "already holds a session"},
      {"add " + map + " " + (tmp / "s1.cmap").string() + " --time yesterday", 2, "'yesterday'"},
      {"add " + map + " " + (tmp / "s1.cmap").string(), 2, "give --time"},
      {"add " + map + " " + (tmp / "missing.cmap").string() + " --time 5", 1, "missing.cmap"},
      {"add " + map + " " + map + " --time 5", 2, "is the input"},
      {"history " + map + " --point 1,2", 2, "X,Y,Z"},
      {"history " + map + " --point 1e9,0,0", 2, "outside the map"},
      {"changes " + map + " --min 0", 2, "--min"},
      {"changes " + map + " -o out.txt", 2, ".ply"},
      {"snapshot " + map + " --at 200 -o x.las", 2, ".cmap, .ply"},
      {"stats " + (tmp / "s0.cmap").string() + " --plot p.png", 2, "4D map"},
      {"build " + map + " " + (tmp / "nowhere").string() + " --times 5", 2, "does not exist"},
  };
  for (const Case& c : cases) {
    const auto r = test::runCommand(cli() + " " + c.args);
    EXPECT_EQ(r.exit_code, c.code) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(bytesOf(map), before) << c.args;
  }
  // A damaged 4D map is reported, never overwritten by add.
  std::ofstream(tmp / "bad.cmap") << "garbage";
  const auto r = test::runCommand(cli() + " add " + (tmp / "bad.cmap").string() + " " + (tmp / "s1.cmap").string() +
                                  " --time 7");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.cmap"), std::string::npos);
  EXPECT_EQ(bytesOf(tmp / "bad.cmap"), std::vector<uint8_t>({'g', 'a', 'r', 'b', 'a', 'g', 'e'}));
}

TEST(TemporalCli, BuildTakesTimesFromTumFolders) {
  test::TempDir tmp;
  // Two tiny TUM folders whose first timestamps order them in reverse of the command line.
  for (int i = 0; i < 2; ++i) {
    const fs::path d = tmp / (i == 0 ? "tum0" : "tum1");
    fs::create_directories(d / "depth");
    ImageU16 depth;
    depth.width = 64;
    depth.height = 48;
    depth.pixels.assign(64 * 48, static_cast<uint16_t>(5000 * (1 + i)));
    writePng(d / "depth" / "0.png", depth);
    const double t = i == 0 ? 2000.0 : 1000.0;
    std::ofstream(d / "depth.txt") << std::fixed << t << " depth/0.png\n";
    std::ofstream(d / "trajectory.txt") << std::fixed << t << " 0 0 0 0 0 0 1\n";
  }
  const std::string map = (tmp / "m.cmap").string();
  auto r = test::runCommand(cli() + " build " + map + " " + (tmp / "tum0").string() + " " + (tmp / "tum1").string() +
                            " --intrinsics 50,50,32,24 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["sessions"], 2);
  ASSERT_EQ(j["added"].size(), 2u);
  EXPECT_EQ(j["added"][0]["time_s"].get<double>(), 1000.0) << "sessions are added in time order";
  const TemporalMap m = readTemporalMap(map);
  // In time order a wall at 2 m (tum1), then at 1 m (tum0): the voxel at 1 m turns from free to
  // occupied.
  const auto key = m.grid().keyOf(Eigen::Vector3d(0.01, 0.01, 1.01));
  ASSERT_TRUE(key);
  const auto h = m.history(*key);
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[0].counters.state(), VoxelState::Free);
  EXPECT_EQ(h[1].counters.state(), VoxelState::Occupied);
  // 3DMatch-style data has no times: build asks for them.
  CHRONOMAP_REQUIRE_DATA(room, "3dmatch/3dmatch");
  r = test::runCommand(cli() + " build " + (tmp / "r.cmap").string() + " " + room.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--times"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "r.cmap"));
}

/// Starts the CLI with `argv` (argv[0] the program name), output discarded; returns its pid.
pid_t spawnCli(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    const int null_fd = open("/dev/null", O_WRONLY);
    dup2(null_fd, 1);
    dup2(null_fd, 2);
    execv(CHRONOMAP_CLI_PATH, args.data());
    _exit(127);
  }
  return pid;
}

/// Runs `argv` (argv[0] the program name) `rounds` times, each on a fresh copy of `old_copy` at
/// `map`, killed (SIGKILL) after a random delay below `max_delay_us`; after each kill the map must
/// be byte for byte `old_bytes` or `new_bytes` and readable. Counts both outcomes.
/// With `interrupted` (appending commands), the map may also be the old bytes followed by part of
/// the new record, which must read as the old map; those outcomes are counted there.
void killAtRandom(const std::vector<std::string>& argv, const fs::path& old_copy, const fs::path& map,
                  const std::vector<uint8_t>& old_bytes, const std::vector<uint8_t>& new_bytes, int rounds,
                  int64_t max_delay_us, uint64_t seed, int& old_seen, int& new_seen, int* interrupted = nullptr) {
  const TemporalMap old_map = readTemporalMap(old_copy);
  std::mt19937_64 rng(seed);
  old_seen = new_seen = 0;
  if (interrupted) *interrupted = 0;
  for (int round = 0; round < rounds; ++round) {
    fs::copy_file(old_copy, map, fs::copy_options::overwrite_existing);
    const pid_t pid = spawnCli(argv);
    ASSERT_GE(pid, 0);
    std::this_thread::sleep_for(
        std::chrono::microseconds(static_cast<int64_t>(rng() % static_cast<uint64_t>(max_delay_us + 1))));
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    const auto now = bytesOf(map);
    if (now == old_bytes) {
      ++old_seen;
    } else if (now == new_bytes) {
      ++new_seen;
    } else {
      ASSERT_TRUE(interrupted) << "round " << round << ": the map is neither the old nor the new one";
      ASSERT_TRUE(now.size() > old_bytes.size() && now.size() < new_bytes.size() &&
                  std::equal(now.begin(), now.end(), new_bytes.begin()) &&
                  std::equal(old_bytes.begin(), old_bytes.end(), now.begin()))
          << "round " << round << ": the map is not the old one with part of an append";
      ASSERT_TRUE(readTemporalMap(map) == old_map) << "round " << round;
      ++*interrupted;
    }
    EXPECT_NO_THROW(readTemporalMap(map));
  }
  EXPECT_EQ(old_seen + new_seen + (interrupted ? *interrupted : 0), rounds);
}

/// Kills `chronomap add` at random moments, writing the map whole and appending: the map on disk
/// must always be the old one or the new one, byte for byte, or (appending) the old one with an
/// unfinished record after it, which reads as the old map and which the next add replaces.
TEST(TemporalCli, KilledAddLeavesOldOrNewMap) {
  test::TempDir tmp;
  writeSessionMap(tmp / "big.cmap", test::randomSessionMap(99, 48, 0.2), {});
  TemporalMap old_map(0.05);
  old_map.add(1000, test::randomSessionMap(98, 48, 0.2));
  writeTemporalMap(tmp / "old.cmap", old_map, {});
  const auto old_bytes = bytesOf(tmp / "old.cmap");
  const fs::path map = tmp / "m.cmap";
  for (const std::string write : {"rewrite", "append"}) {
    fs::copy_file(tmp / "old.cmap", map, fs::copy_options::overwrite_existing);
    const std::vector<std::string> argv = {"chronomap", "add",    map.string(), (tmp / "big.cmap").string(),
                                           "--time",    "2000",   "--write",    write};
    std::string add = cli();
    for (size_t i = 1; i < argv.size(); ++i) add += " " + argv[i];
    const auto start = std::chrono::steady_clock::now();
    ASSERT_EQ(test::runCommand(add).exit_code, 0);
    const auto full_us =
        std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - start).count();
    const auto new_bytes = bytesOf(map);
    ASSERT_NE(new_bytes, old_bytes);
    if (write == "append") {
      ASSERT_TRUE(std::equal(old_bytes.begin(), old_bytes.end(), new_bytes.begin())) << "append rewrote bytes";
    }
    int old_seen = 0, new_seen = 0, interrupted = 0;
    const int rounds = test::underSanitizer() ? 10 : 30;
    killAtRandom(argv, tmp / "old.cmap", map, old_bytes, new_bytes, rounds, 2 * full_us, 5, old_seen, new_seen,
                 write == "append" ? &interrupted : nullptr);
    std::cout << "killed add --write " << write << ": " << old_seen << " old, " << new_seen << " new, " << interrupted
              << " interrupted appends of " << rounds << " (full run " << full_us << " us)\n";
    if (write == "append") {
      // Kills at random moments rarely land inside the write itself: also kill as soon as the
      // file starts to grow.
      const TemporalMap before = readTemporalMap(tmp / "old.cmap");
      int cut = 0;
      const int write_rounds = test::underSanitizer() ? 4 : 10;
      for (int round = 0; round < write_rounds; ++round) {
        fs::copy_file(tmp / "old.cmap", map, fs::copy_options::overwrite_existing);
        const pid_t pid = spawnCli(argv);
        ASSERT_GE(pid, 0);
        int status = 0;
        while (fs::file_size(map) == old_bytes.size() && waitpid(pid, &status, WNOHANG) == 0) {
        }
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        const auto now = bytesOf(map);
        ASSERT_TRUE(std::equal(now.begin(), now.end(), new_bytes.begin()) && now.size() >= old_bytes.size());
        if (now.size() < new_bytes.size()) {
          ++cut;
          ASSERT_TRUE(readTemporalMap(map) == before) << "an interrupted append does not read as the old map";
        }
      }
      std::cout << "killed add --write append while writing: " << cut << " of " << write_rounds
                << " left part of the record\n";
    }
    // The next add finishes the job: temporaries of killed writers are removed and an unfinished
    // record (here half of one) is replaced.
    std::vector<uint8_t> left = old_bytes;
    if (write == "append") {
      left.insert(left.end(), new_bytes.begin() + std::ssize(old_bytes),
                  new_bytes.begin() + std::ssize(old_bytes) + std::ssize(new_bytes) / 2 - std::ssize(old_bytes) / 2);
    }
    {
      std::ofstream out(map, std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(left.data()), std::ssize(left));
    }
    ASSERT_EQ(test::runCommand(add).exit_code, 0);
    EXPECT_EQ(bytesOf(map), new_bytes);
    for (const auto& e : fs::directory_iterator(tmp.path())) {
      EXPECT_EQ(e.path().filename().string().find(".m.cmap.tmp-"), std::string::npos) << e.path();
    }
  }
}

/// `chronomap add` appends: the bytes already in the file stay as they are, `stats` counts the
/// appended sessions, `--write rewrite` folds them in, and the map reads the same either way.
TEST(TemporalCli, AddAppendsWithoutRewriting) {
  test::TempDir tmp;
  for (int i = 0; i < 4; ++i) {
    writeSessionMap(tmp / ("s" + std::to_string(i) + ".cmap"), test::randomSessionMap(40 + i, 32, 0.2), {});
  }
  const fs::path map = tmp / "m.cmap";
  auto add = [&](int i, const std::string& time, const std::string& extra) {
    const auto r = test::runCommand(cli() + " add " + map.string() + " " + (tmp / ("s" + std::to_string(i) + ".cmap")).string() +
                                    " --time " + time + " --json " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return nlohmann::json::parse(r.out);
  };
  EXPECT_FALSE(add(0, "1000", "")["appended"].get<bool>());  // created: written whole
  auto before = bytesOf(map);
  EXPECT_TRUE(add(1, "2000", "--write append")["appended"].get<bool>());
  auto after = bytesOf(map);
  ASSERT_GT(after.size(), before.size());
  EXPECT_TRUE(std::equal(before.begin(), before.end(), after.begin()));
  before = after;
  EXPECT_TRUE(add(2, "500", "--write append")["appended"].get<bool>());  // out of time order
  after = bytesOf(map);
  EXPECT_TRUE(std::equal(before.begin(), before.end(), after.begin()));
  auto stats = nlohmann::json::parse(test::runCommand(cli() + " stats --json " + map.string()).out);
  EXPECT_EQ(stats["appended_sessions"], 2);
  EXPECT_EQ(stats["sessions"], 3);
  const TemporalMap appended = readTemporalMap(map);
  // auto: the appended records now outweigh the base, so this add writes the map whole.
  fs::copy_file(map, tmp / "copy.cmap");
  EXPECT_FALSE(add(3, "3000", "")["appended"].get<bool>());
  stats = nlohmann::json::parse(test::runCommand(cli() + " stats --json " + map.string()).out);
  EXPECT_EQ(stats["appended_sessions"], 0);
  EXPECT_EQ(stats["sessions"], 4);
  // The same four sessions added to the copy by appending give the same map.
  const auto r = test::runCommand(cli() + " add " + (tmp / "copy.cmap").string() + " " + (tmp / "s3.cmap").string() +
                                  " --time 3000 --write append");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  TemporalMap a = readTemporalMap(map), b = readTemporalMap(tmp / "copy.cmap");
  a.compact();
  b.compact();
  EXPECT_TRUE(a == b);
  EXPECT_EQ(appended.times(), (std::vector<double>{500, 1000, 2000}));
  EXPECT_EQ(a.times(), (std::vector<double>{500, 1000, 2000, 3000}));
  // A bad --write is a usage error and leaves the map alone.
  const auto bytes = bytesOf(map);
  EXPECT_EQ(test::runCommand(cli() + " add " + map.string() + " " + (tmp / "s3.cmap").string() +
                             " --time 4000 --write sometimes")
                .exit_code,
            2);
  EXPECT_EQ(bytesOf(map), bytes);
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

TEST(SimulatorCli, SimulateAndBuildWithRegistration) {
  test::TempDir tmp;
  auto r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " simulate --preset tiny --sessions 2 --resolution-scale 0.2 -o " +
                            (tmp / "sim").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["sessions"], 2);
  EXPECT_TRUE(fs::exists(tmp / "sim" / "session_01" / "trajectory.txt"));
  EXPECT_TRUE(fs::exists(tmp / "sim" / "truth" / "occupancy_01.cmap"));
  // The simulated sessions are ordinary TUM folders: build takes their times.
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "m.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " " + (tmp / "sim" / "session_01").string() +
                       " --fast --json --register --register-rounds 1 --realign");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto built = nlohmann::json::parse(r.out);
  EXPECT_EQ(built["sessions"], 2);
  // Plain --register: the library's defaults, no preset's.
  ASSERT_TRUE(built.contains("registration")) << r.out;
  EXPECT_EQ(built["registration"]["preset"], "none");
  EXPECT_EQ(built["registration"]["rounds"], 1);
  EXPECT_EQ(built["registration"]["radius_voxels"], 2.0);
  EXPECT_EQ(built["registration"]["drift_rounds"], 0);
  EXPECT_EQ(built["registration"]["planar"], false);
  EXPECT_EQ(built["registration"]["keep_mean"], false);
  for (const auto& a : built["added"]) {
    EXPECT_TRUE(a.contains("realigned_voxels"));
    EXPECT_FALSE(a.contains("drift_correction_max_m"));  // no drift correction
    ASSERT_TRUE(a.contains("registration_m"));
    EXPECT_LT(std::abs(a["registration_m"][0].get<double>()), 0.2);  // a correction of centimetres
    EXPECT_EQ(a["registration_model"], "world");  // the default
  }
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "w.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " " + (tmp / "sim" / "session_01").string() +
                       " --fast --json --register --register-rounds 1 --register-model per-pose --register-radius 1.5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto per_pose = nlohmann::json::parse(r.out);
  for (const auto& a : per_pose["added"]) EXPECT_EQ(a["registration_model"], "per-pose");
  // Drift: per-frame corrections after the rigid round, reported by their largest translation.
  // Here on the odometry preset, whose knots along the path --register-drift replaces.
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "d.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " " + (tmp / "sim" / "session_01").string() +
                       " --fast --json --register-preset odometry --register-rounds 1 --register-drift 5"
                       " --register-drift-rounds 1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto drift = nlohmann::json::parse(r.out);
  for (const auto& a : drift["added"]) {
    ASSERT_TRUE(a.contains("drift_correction_max_m"));
    EXPECT_LT(a["drift_correction_max_m"].get<double>(), 0.2);
  }
  // What ran: the preset's settings, the flags given replacing three of them.
  ASSERT_TRUE(drift.contains("registration")) << r.out;
  const auto& used = drift["registration"];
  EXPECT_EQ(used["preset"], "odometry");
  EXPECT_EQ(used["rounds"], 1);
  EXPECT_EQ(used["drift_knot_frames"], 5);
  EXPECT_EQ(used["drift_knot_m"], 0.0);
  EXPECT_EQ(used["drift_rounds"], 1);
  EXPECT_EQ(used["radius_voxels"], 6.0);
  EXPECT_EQ(used["fine_radius_voxels"], 3.0);
  EXPECT_EQ(used["planar"], true);
  EXPECT_EQ(used["points"], true);
  EXPECT_EQ(used["keep_mean"], true);
  EXPECT_EQ(used["model"], "world");
  for (int c = 0; c < 2; ++c) {  // the mean kept: the two sessions' rigid corrections are opposite
    EXPECT_NEAR(drift["added"][0]["registration_m"][c].get<double>() +
                    drift["added"][1]["registration_m"][c].get<double>(),
                0.0, 1e-6);
  }
  EXPECT_NEAR(drift["added"][0]["registration_m"][2].get<double>(), 0.0, 1e-9);  // planar
  // Planar, drift on points: no vertical correction; a drift correction of centimetres. As the
  // localiser preset, with its knots every 20 frames replaced and a heading prior given.
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "p.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " " + (tmp / "sim" / "session_01").string() +
                       " --fast --json --register-preset localiser --register-rounds 1 --register-drift 5"
                       " --register-drift-yaw 0.05");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto points = nlohmann::json::parse(r.out);
  EXPECT_EQ(points["registration"]["preset"], "localiser");
  EXPECT_EQ(points["registration"]["drift_knot_frames"], 5);
  EXPECT_EQ(points["registration"]["drift_yaw_per_frame_deg"], 0.05);
  EXPECT_EQ(points["registration"]["radius_voxels"], 2.0);
  EXPECT_EQ(points["registration"]["planar"], true);
  EXPECT_EQ(points["registration"]["points"], true);
  EXPECT_EQ(points["registration"]["keep_mean"], false);
  for (const auto& a : points["added"]) {
    ASSERT_TRUE(a.contains("registration_m"));
    EXPECT_NEAR(a["registration_m"][2].get<double>(), 0.0, 1e-9);
    ASSERT_TRUE(a.contains("drift_correction_max_m"));
    EXPECT_LT(a["drift_correction_max_m"].get<double>(), 0.2);
  }
  // Keep the mean: the two sessions' rigid corrections are opposite, the map stays between them.
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "k.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " " + (tmp / "sim" / "session_01").string() +
                       " --fast --json --register --register-rounds 1 --register-planar --register-keep-mean"
                       " --register-drift 5 --register-drift-yaw 0.05 --register-drift-rounds 2 --register-fine-radius 1.5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto kept = nlohmann::json::parse(r.out);
  ASSERT_EQ(kept["added"].size(), 2u);
  for (int c = 0; c < 2; ++c) {
    const double a = kept["added"][0]["registration_m"][c].get<double>(),
                 b = kept["added"][1]["registration_m"][c].get<double>();
    EXPECT_NEAR(a + b, 0.0, 1e-6) << c;
  }
  EXPECT_GT(std::abs(kept["added"][0]["registration_m"][0].get<double>()) +
                std::abs(kept["added"][0]["registration_m"][1].get<double>()),
            1e-4);  // the sessions did move against each other
  for (const auto& a : kept["added"]) EXPECT_TRUE(a.contains("drift_correction_max_m"));
  // Drift knots along the sensor's path instead of by frames.
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "path.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " " + (tmp / "sim" / "session_01").string() +
                       " --fast --json --register --register-rounds 1 --register-planar --register-points"
                       " --register-drift-path 0.5 --register-drift-rounds 2 --register-fine-radius 1.5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto path = nlohmann::json::parse(r.out);
  ASSERT_EQ(path["added"].size(), 2u);
  for (const auto& a : path["added"]) {
    ASSERT_TRUE(a.contains("drift_correction_max_m"));
    EXPECT_GT(a["drift_correction_max_m"].get<double>(), 0.0);  // it did correct
    EXPECT_LT(a["drift_correction_max_m"].get<double>(), 0.2);
  }
  for (const auto& [bad, flag] : std::vector<std::pair<const char*, const char*>>{
           {" --register-planar", "--register-planar"}, {" --register --register-points", "--register-points"},
           {" --register-cache 1", "--register-cache"}, {" --register-keep-mean", "--register-keep-mean"}}) {
    r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                         (tmp / "sim" / "session_00").string() + bad);
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_NE(r.err.find(std::string(flag) + " needs"), std::string::npos) << bad << ": " << r.err;
    EXPECT_FALSE(fs::exists(tmp / "n.cmap"));
  }
  for (const char* bad : {" --register --register-drift-yaw 0.05", " --register --register-drift 5 --register-drift-yaw 0",
                          " --register --register-drift 5 --register-drift-yaw nan"}) {
    r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                         (tmp / "sim" / "session_00").string() + bad);
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_NE(r.err.find("--register-drift-yaw"), std::string::npos) << bad << ": " << r.err;
    EXPECT_FALSE(fs::exists(tmp / "n.cmap"));
  }
  for (const auto& [bad, flag] : std::vector<std::pair<const char*, const char*>>{
           {" --register --register-drift-rounds 3", "--register-drift-rounds needs"},
           {" --register --register-drift-rounds 2", "--register-drift-rounds needs"},  // the default, given
           {" --register --register-drift-yaw 0.01", "--register-drift-yaw needs"},     // likewise
           {" --register-radius 2", "--register-radius needs"},
           {" --register --register-drift 5 --register-drift-rounds 0", "--register-drift-rounds must"},
           {" --register --register-fine-radius 2", "--register-fine-radius needs"},
           {" --register --register-drift 5 --register-fine-radius 0.5", "--register-fine-radius must"},
           {" --register --register-drift 5 --register-fine-radius nan", "--register-fine-radius"},
           {" --register-drift-path 1", "--register-drift-path needs --register"},
           {" --register --register-drift 5 --register-drift-path 1", "give one of them"},
           {" --register --register-drift-path 0", "--register-drift-path must"},
           {" --register --register-drift-path nan", "--register-drift-path"},
           {" --register --register-drift-path 1 --register-drift-yaw 0.05", "per metre"},
           {" --register-preset odometry --register-drift-yaw 0.05", "per metre"},  // the preset's knots by path
           {" --register-preset odometry --register-drift 0 --register-fine-radius 2", "--register-fine-radius needs"},
           {" --register-preset odometry --register-drift 5 --register-drift-path 1", "give one of them"},
           {" --register-preset odometry --register-radius 9", "--register-radius must"},
           {" --register-preset sideways", "--register-preset"},
           {" --register-rounds 2", "--register-rounds needs"},
           {" --register-model per-pose", "--register-model needs"}}) {
    r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                         (tmp / "sim" / "session_00").string() + bad);
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_NE(r.err.find(flag), std::string::npos) << bad << ": " << r.err;
    EXPECT_FALSE(fs::exists(tmp / "n.cmap"));
  }
  for (const char* bad : {" --register-drift 5", " --register --register-drift -1"}) {
    r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                         (tmp / "sim" / "session_00").string() + bad);
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_NE(r.err.find("--register-drift"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(tmp / "n.cmap"));
  }
  for (const char* bad : {" --register-radius 1.5", " --register --register-radius 0.5",
                          " --register --register-radius nan"}) {
    r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                         (tmp / "sim" / "session_00").string() + bad);
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_NE(r.err.find("--register-radius"), std::string::npos) << bad << ": " << r.err;
    EXPECT_FALSE(fs::exists(tmp / "n.cmap"));
  }
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " --register --register-model sideways");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("must be world or per-pose, not 'sideways'"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "n.cmap"));
  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " build " + (tmp / "n.cmap").string() + " " +
                       (tmp / "sim" / "session_00").string() + " --register --register-rounds 0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_FALSE(fs::exists(tmp / "n.cmap"));

  r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " simulate --preset castle -o " + (tmp / "x").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown simulator preset 'castle'"), std::string::npos) << r.err;
}

/// The main job, at a fifth of the resolution: its figures, its report's pictures and the tour.
/// (Apart from the test above so that the two long runs can go in parallel.)
TEST(SimulatorCli, Demo) {
  test::TempDir tmp;
  const auto r = test::runCommand(std::string(CHRONOMAP_CLI_PATH) + " demo --resolution-scale 0.2 -o " + (tmp / "demo").string() +
                       " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto d = nlohmann::json::parse(r.out);
  EXPECT_EQ(d["sessions"], 6);
  EXPECT_GT(d["precision"].get<double>(), 0.5);
  // Registration brings the sessions closer to the truth than their recorded poses.
  EXPECT_GT(d["precision"].get<double>(), d["precision_as_recorded"].get<double>());
  EXPECT_GT(d["events_found"].get<int>(), 0);
  EXPECT_LT(d["nodes_4d"].get<uint64_t>(), d["nodes_separate"].get<uint64_t>());
  const std::string report = readTextFile(tmp / "demo" / "report.md");
  for (const char* image : {"map_topview.png", "session_01_cloud.png", "frame_rgb.png", "frame_depth.png",
                            "trajectory.png", "storage.png"}) {
    EXPECT_NE(report.find(std::string("images/") + image), std::string::npos) << image;
    EXPECT_GT(fs::file_size(tmp / "demo" / "images" / image), 500u) << image;
  }
  EXPECT_TRUE(fs::exists(tmp / "demo" / "office.cmap"));
  // The tour: the viewer with the map inside, linked from the report.
  EXPECT_NE(report.find("(tour.html)"), std::string::npos);
  const std::string tour = readTextFile(tmp / "demo" / "tour.html");
  EXPECT_NE(tour.find("id=\"chronomap-data\""), std::string::npos);
  EXPECT_GT(tour.size(), 500000u);  // the bundle and the data
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

/// Kills `chronomap build` at random moments: the map on disk is the old one or the new one.
TEST(TemporalCli, KilledBuildLeavesOldOrNewMap) {
  test::TempDir tmp;
  const std::string cli_path = CHRONOMAP_CLI_PATH;
  ASSERT_EQ(test::runCommand(cli_path + " simulate --preset tiny --sessions 3 --resolution-scale 0.3 -o " +
                             (tmp / "sim").string())
                .exit_code,
            0);
  const fs::path map = tmp / "m.cmap";
  const std::string first = cli_path + " build " + map.string() + " " + (tmp / "sim" / "session_00").string();
  ASSERT_EQ(test::runCommand(first).exit_code, 0);
  fs::copy_file(map, tmp / "old.cmap");
  const auto old_bytes = bytesOf(map);
  const std::vector<std::string> args = {"chronomap", "build", map.string(), (tmp / "sim" / "session_01").string(),
                                         (tmp / "sim" / "session_02").string()};
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(test::runCommand(cli_path + " build " + args[2] + " " + args[3] + " " + args[4]).exit_code, 0);
  const auto full_us =
      std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - start).count();
  const auto new_bytes = bytesOf(map);
  ASSERT_NE(new_bytes, old_bytes);
  int old_seen = 0, new_seen = 0;
  killAtRandom(args, tmp / "old.cmap", map, old_bytes, new_bytes, 15, full_us + full_us / 4, 9, old_seen, new_seen);
  std::cout << "killed build: " << old_seen << " old, " << new_seen << " new of 15 (full run " << full_us << " us)\n";
}

}  // namespace
}  // namespace chronomap
