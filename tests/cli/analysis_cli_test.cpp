// chronomap diff and segment on the command line: results equal the library's, JSON keys,
// 4D times, and bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/core/file.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/store/temporal_file.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::at;
using test::cli;

VoxelCounters occupied() {
  VoxelCounters c;
  c.length_m = 0.1f;
  c.hits = 3;
  c.red = 3 * 200;
  return c;
}

VoxelCounters freeVoxel() {
  VoxelCounters c;
  c.length_m = 0.2f;
  return c;
}

// A floor of 10x10 free voxels; `b` has a 2x2x2 box on it and a separate voxel.
void writePair(const fs::path& a, const fs::path& b) {
  SessionMap ma(0.05), mb(0.05);
  for (int z = 0; z < 4; ++z) {
    for (int y = 0; y < 10; ++y) {
      for (int x = 0; x < 10; ++x) {
        ma.add(at(x, y, z), freeVoxel());
        const bool box = x >= 2 && x < 4 && y >= 2 && y < 4 && z < 2;
        const bool lone = x == 8 && y == 8 && z == 0;
        mb.add(at(x, y, z), box || lone ? occupied() : freeVoxel());
      }
    }
  }
  writeSessionMap(a, ma, {});
  writeSessionMap(b, mb, {});
}

TEST(AnalysisCli, HelpForEveryCommand) {
  for (const char* cmd : {"diff", "segment"}) {
    const auto r = test::runCommand(cli() + " " + cmd + " --help");
    EXPECT_EQ(r.exit_code, 0) << cmd;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << cmd;
  }
}

/// The analytic changes scene (builders.h) as a 4D map of two sessions, at 100 s and 200 s.
TemporalMap writeChangesScene(const fs::path& path) {
  TemporalMap map(0.05);
  map.add(100.0, test::changesScene(false));
  map.add(200.0, test::changesScene(true));
  writeTemporalMap(path, map, {});
  return map;
}

TEST(AnalysisCli, DiffWithoutFlagsGivesTheRecommendedAnswer) {
  test::TempDir tmp;
  const std::string m = (tmp / "m.cmap").string();
  const TemporalMap map = writeChangesScene(m);
  const Changes expected = findChanges(map, 100.0, 200.0);  // the library's defaults
  ASSERT_EQ(expected.objects.size(), 3u);
  auto run = [&](const std::string& out, const std::string& flags) {
    const auto r = test::runCommand(cli() + " diff " + m + "@100 " + m + "@200 -o " + (tmp / out).string() + flags);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r;
  };
  const auto plain = run("d.cmap", " --json");
  const auto j = nlohmann::json::parse(plain.out);
  EXPECT_EQ(j["objects"], changedObjectsJson(expected.objects));
  EXPECT_EQ(j["preset"], "recommended");
  EXPECT_EQ(j["mode"], "band");
  EXPECT_EQ(j["settings"], changeSettingsJson(recommendedChangeSettings()));
  EXPECT_EQ(j["changed_voxels"], expected.appeared_voxels + expected.vanished_voxels);
  EXPECT_EQ(j["objects"][2]["kind"], "moved");
  // The file holds the same diff, and the objects and settings in its metadata.
  EXPECT_EQ(readDiffMap(tmp / "d.cmap"), expected.diff);
  const nlohmann::json kept = diffChangesOf(readCmap(tmp / "d.cmap"), "d.cmap");
  EXPECT_EQ(kept["objects"], changedObjectsJson(expected.objects));
  EXPECT_EQ(kept["settings"], changeSettingsJson(recommendedChangeSettings()));
  EXPECT_EQ(kept["preset"], "recommended");

  // --preset raw: the plain hard diff; the patch before the wall is a change there, the small box
  // an object, and the moved box two.
  const auto raw = nlohmann::json::parse(run("raw.cmap", " --preset raw --json").out);
  const Changes plain_diff = findChanges(map, 100.0, 200.0, rawChangeSettings());
  EXPECT_EQ(readDiffMap(tmp / "raw.cmap"), diff(map, 100.0, 200.0));
  EXPECT_EQ(raw["objects"], changedObjectsJson(plain_diff.objects));
  EXPECT_EQ(raw["objects"].size(), 6u);
  EXPECT_EQ(raw["mode"], "hard");
  EXPECT_NE(raw["changed_voxels"], j["changed_voxels"]);
  EXPECT_NE(readDiffMap(tmp / "raw.cmap"), readDiffMap(tmp / "d.cmap"));

  // Expert flags change single settings: raw plus the recommended flags is the default answer,
  // and the default with --min-voxels 1 keeps the small box too.
  const auto spelled = nlohmann::json::parse(
      run("s.cmap", " --preset raw --mode band --neighbourhood 1 --min-shift 0.5 --shift-plane 0.15 --kept-surface 3 "
                    "--dark-surface 2 "
                    "--seen-at-both --connectivity vertex --min-voxels 20 --moves --json")
          .out);
  EXPECT_EQ(spelled["objects"], j["objects"]);
  EXPECT_EQ(spelled["settings"], j["settings"]);
  EXPECT_EQ(spelled["preset"], "raw, changed by flags");
  const auto small = nlohmann::json::parse(run("m1.cmap", " --min-voxels 1 --json").out);
  EXPECT_EQ(small["objects"].size(), 4u);
  EXPECT_EQ(small["settings"]["segment"]["min_voxels"], 1);
  const auto apart = nlohmann::json::parse(run("nm.cmap", " --no-moves --json").out);
  EXPECT_EQ(apart["objects"].size(), 4u);
  const auto both = test::runCommand(cli() + " diff " + m + "@100 " + m + "@200 --moves --no-moves -o " +
                                     (tmp / "b.cmap").string());
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_NE(both.err.find("--moves and --no-moves were both given"), std::string::npos) << both.err;

  // Text: the objects, the move with its distance.
  const auto text = run("t.cmap", "");
  EXPECT_NE(text.out.find("band diff (recommended settings): "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("3 objects: 1 appeared, 1 vanished, 1 moved"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find(", 0.90 m\n"), std::string::npos) << text.out;
}

TEST(AnalysisCli, DiffHelpPrintsTheDefaults) {
  const auto r = test::runCommand(cli() + " diff --help");
  ASSERT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("--mode band --alpha 0.1 --neighbourhood 1 --min-shift 0.5 --shift-plane 0.15 --kept-surface 3"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("--connectivity vertex --min-voxels 20 --moves"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("raw (the plain thesis diff"), std::string::npos) << r.out;
  const auto bad = test::runCommand(cli() + " diff a.cmap b.cmap --preset fancy -o d.cmap");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--preset 'fancy' is not a preset: give recommended (the default) or raw"), std::string::npos)
      << bad.err;
}

TEST(AnalysisCli, DiffThenSegmentFindsTheBox) {
  test::TempDir tmp;
  writePair(tmp / "a.cmap", tmp / "b.cmap");
  const auto d = test::runCommand(cli() + " diff " + (tmp / "a.cmap").string() + " " + (tmp / "b.cmap").string() +
                                  " -o " + (tmp / "d.cmap").string() + " --ply " + (tmp / "d.ply").string() +
                                  " --json --preset raw");
  ASSERT_EQ(d.exit_code, 0) << d.err;
  const auto dj = nlohmann::json::parse(d.out);
  EXPECT_EQ(dj["mode"], "hard");
  EXPECT_EQ(dj["changed_voxels"], 9);
  EXPECT_EQ(dj["appeared"], 9);
  EXPECT_EQ(dj["vanished"], 0);
  EXPECT_TRUE(fs::exists(tmp / "d.ply"));
  const DiffMap file = readDiffMap(tmp / "d.cmap");
  EXPECT_EQ(file, diff(readSessionMap(tmp / "a.cmap"), readSessionMap(tmp / "b.cmap")));

  const auto s = test::runCommand(cli() + " segment " + (tmp / "d.cmap").string() + " --json -o " +
                                  (tmp / "parts").string());
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const auto sj = nlohmann::json::parse(s.out);
  ASSERT_EQ(sj["components"].size(), 2u);
  const auto& box = sj["components"][0];
  EXPECT_EQ(box["id"], 1);
  EXPECT_EQ(box["voxels"], 8);
  EXPECT_EQ(box["kind"], "appeared");
  EXPECT_NEAR(box["volume_m3"].get<double>(), 8 * 0.05 * 0.05 * 0.05, 1e-12);
  for (int i = 0; i < 3; ++i) {
    const double lo = i == 2 ? 0.0 : 0.10, hi = i == 2 ? 0.10 : 0.20;
    EXPECT_NEAR(box["bbox_min"][i].get<double>(), lo, 1e-9);
    EXPECT_NEAR(box["bbox_max"][i].get<double>(), hi, 1e-9);
    EXPECT_NEAR(box["centroid"][i].get<double>(), (lo + hi) / 2, 1e-9);
  }
  EXPECT_EQ(box["mean_color"][0], 200);
  EXPECT_EQ(sj["components"][1]["voxels"], 1);
  EXPECT_EQ(readDiffMap(tmp / "parts" / "component_0001.cmap").voxelCount(), 8u);
  EXPECT_TRUE(fs::exists(tmp / "parts" / "component_0002.ply"));
  EXPECT_TRUE(fs::exists(tmp / "parts" / "components.json"));

  const auto small = test::runCommand(cli() + " segment " + (tmp / "d.cmap").string() + " --min-voxels 2 --json");
  ASSERT_EQ(small.exit_code, 0) << small.err;
  EXPECT_EQ(nlohmann::json::parse(small.out)["components"].size(), 1u);
  EXPECT_EQ(nlohmann::json::parse(small.out)["dropped"], 1);

  const auto stats = test::runCommand(cli() + " stats " + (tmp / "d.cmap").string() + " --json");
  ASSERT_EQ(stats.exit_code, 0) << stats.err;
  EXPECT_EQ(nlohmann::json::parse(stats.out)["kind"], "diff");
  EXPECT_EQ(nlohmann::json::parse(stats.out)["changed_voxels"], 9);
}

TEST(AnalysisCli, DiffOfTwoTimesOfA4DMap) {
  test::TempDir tmp;
  writePair(tmp / "a.cmap", tmp / "b.cmap");
  TemporalMap map(0.05);
  map.add(100, readSessionMap(tmp / "a.cmap"));
  map.add(200, readSessionMap(tmp / "b.cmap"));
  writeTemporalMap(tmp / "m.cmap", map, {});
  const std::string m = (tmp / "m.cmap").string();
  const auto r = test::runCommand(cli() + " diff " + m + "@150 " + m + "@200 --preset raw --mode band -o " +
                                  (tmp / "d.cmap").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["changed_voxels"], 9);
  // A session map against a 4D map time: nothing changed since b.
  const auto same = test::runCommand(cli() + " diff " + (tmp / "b.cmap").string() + " " + m + "@200 -o " +
                                     (tmp / "e.cmap").string() + " --json");
  ASSERT_EQ(same.exit_code, 0) << same.err;
  EXPECT_EQ(nlohmann::json::parse(same.out)["changed_voxels"], 0);
}

TEST(AnalysisCli, DiffKeepsItsNeighbourhoodSettings) {
  test::TempDir tmp;
  writePair(tmp / "a.cmap", tmp / "b.cmap");
  const auto r = test::runCommand(cli() + " diff " + (tmp / "a.cmap").string() + " " + (tmp / "b.cmap").string() +
                                  " --mode band --neighbourhood 1 --min-shift 0.5 --shift-plane 0.3 --kept-surface 3" +
                                  " --kept-share 0.8" +
                                  " --dark-surface 2 --dark-below 50 --dark-contrast 0.5 --dark-share 0.7 -o " +
                                  (tmp / "d.cmap").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const DiffMap d = readDiffMap(tmp / "d.cmap");
  EXPECT_EQ(d.settings().neighbourhood_voxels, 1);
  EXPECT_EQ(d.settings().min_shift_voxels, 0.5);
  EXPECT_EQ(d.settings().shift_plane_ratio, 0.3);
  EXPECT_EQ(d.settings().kept_surface_radius_voxels, 3);
  EXPECT_EQ(d.settings().kept_surface_share, 0.8);
  EXPECT_EQ(d.settings().dark_surface_radius_voxels, 2);
  EXPECT_EQ(d.settings().dark_surface_brightness, 50.0);
  EXPECT_EQ(d.settings().dark_surface_contrast, 0.5);
  EXPECT_EQ(d.settings().dark_surface_share, 0.7);
  EXPECT_EQ(d.voxelCount(), 9u) << "a never saw anything occupied: the box and the lone voxel stay";
}

TEST(AnalysisCli, BadInputGetsOneClearMessage) {
  test::TempDir tmp;
  writePair(tmp / "a.cmap", tmp / "b.cmap");
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string(), out = (tmp / "d.cmap").string();
  struct Case {
    std::string args;
    int code;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"diff " + a + " " + b + " --mode soft -o " + out, 2, "unknown diff mode"},
      {"diff " + a + " " + b + " --mode threshold --alpha 1.5 -o " + out, 2, "alpha"},
      {"diff " + a + " " + b + " -o " + (tmp / "d.txt").string(), 2, "must end in .cmap"},
      {"diff " + a + " " + b + " --neighbourhood 1 --min-shift -0.5 -o " + out, 2, "min shift"},
      {"diff " + a + " " + b + " --neighbourhood 1 --min-shift 0.5 --shift-plane 1.5 -o " + out, 2, "shift plane ratio"},
      {"diff " + a + " " + b + " --kept-surface 5 -o " + out, 2, "kept-surface radius"},
      {"diff " + a + " " + b + " --kept-surface 3 --kept-share 0 -o " + out, 2, "kept-surface share"},
      {"diff " + a + " " + b + " --dark-surface 5 -o " + out, 2, "dark-surface radius"},
      {"diff " + a + " " + b + " --dark-surface 3 --dark-below 300 -o " + out, 2, "dark-surface brightness"},
      {"diff " + a + " " + b + " --dark-surface 3 --dark-contrast 0 -o " + out, 2, "dark-surface contrast"},
      {"diff " + a + " " + b + " --dark-surface 2 --dark-share 1.5 -o " + out, 2, "dark-surface share"},
      {"diff " + a + "@100 " + b + " -o " + out, 2, "is a session map"},
      {"diff " + a + " " + (tmp / "missing.cmap").string() + " -o " + out, 1, "missing.cmap"},
      {"segment " + a, 1, "not a diff"},
      {"segment " + (tmp / "missing.cmap").string(), 1, "missing.cmap"},
      {"segment " + out + " --connectivity corner", 2, "unknown connectivity"},
  };
  for (const Case& c : cases) {
    const auto r = test::runCommand(cli() + " " + c.args);
    EXPECT_EQ(r.exit_code, c.code) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out)) << "no diff written after: " << c.args;
  }
  // A 4D map without a time.
  TemporalMap map(0.05);
  map.add(100, readSessionMap(a));
  writeTemporalMap(tmp / "m.cmap", map, {});
  const auto r = test::runCommand(cli() + " diff " + (tmp / "m.cmap").string() + " " + b + " -o " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("@TIME"), std::string::npos) << r.err;
  // Truncated and corrupt diffs.
  ASSERT_EQ(test::runCommand(cli() + " diff " + a + " " + b + " -o " + out).exit_code, 0);
  std::vector<uint8_t> bytes = readFileBytes(out);
  const fs::path cut = tmp / "cut.cmap", flipped = tmp / "flipped.cmap";
  writeFileAtomic(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() / 2)));
  bytes[bytes.size() - 5] ^= 0x40;
  writeFileAtomic(flipped, bytes);
  for (const fs::path& bad : {cut, flipped}) {
    const auto s = test::runCommand(cli() + " segment " + bad.string());
    EXPECT_EQ(s.exit_code, 1) << bad;
    EXPECT_NE(s.err.find(bad.filename().string()), std::string::npos) << s.err;
  }
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

/// A session observing a 16 x 8 x 4 block, free but for a 3 x 3 x 3 box at x0 (none when < 0).
SessionMap blockWithBox(int x0) {
  SessionMap s(0.05);
  for (int z = 0; z < 4; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 16; ++x) {
        const bool box = x0 >= 0 && x >= x0 && x < x0 + 3 && y >= 2 && y < 5 && z >= 1;
        s.add(at(x, y, z), box ? occupied() : freeVoxel());
      }
    }
  }
  return s;
}

TEST(AnalysisCli, AlertsRankTheSessionsChangesWithReasons) {
  test::TempDir tmp;
  // Twelve sessions, twice a day: a box at x 2 every morning, gone every evening; in the last
  // (a morning) it comes back and a second box stands at x 10, where nothing ever stood.
  TemporalMap map(0.05);
  const double monday = 1330905600.0;
  for (int i = 0; i < 12; ++i) map.add(monday + 86400.0 * (i / 2) + 3600.0 * (i % 2 ? 20.0 : 9.0), blockWithBox(i % 2 ? -1 : 2));
  const double last = monday + 86400.0 * 6 + 3600.0 * 9.0;
  SessionMap both = blockWithBox(2);
  both.merge(blockWithBox(10));
  map.add(last, both);
  writeTemporalMap(tmp / "m.cmap", map, {});
  const std::string m = (tmp / "m.cmap").string();
  auto r = test::runCommand(cli() + " alerts " + m + " --at 2012-03-11T09:00:00Z --json --min-voxels 5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["alerts"].size(), 2u);
  EXPECT_EQ(j["history_sessions"], 12);
  EXPECT_EQ(j["alerts"][0]["rank"], 1);
  EXPECT_EQ(j["alerts"][0]["reason"], "this space was free in all 12 earlier observations");
  EXPECT_GT(j["alerts"][0]["centroid"][0].get<double>(), j["alerts"][1]["centroid"][0].get<double>());
  EXPECT_GT(j["alerts"][0]["score_bits"].get<double>(), j["alerts"][1]["score_bits"].get<double>() + 2.0);
  // --top 1 lists one; -o writes the pictures and a PLY per object.
  r = test::runCommand(cli() + " alerts " + m + " --at 2012-03-11T09:00:00Z --top 1 --min-voxels 5 -o " +
                       (tmp / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("2 changed objects"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("  2. "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("free in all 12 earlier observations"), std::string::npos) << r.out;
  for (const char* f : {"alerts.json", "alerts.png", "alert_01.png", "alert_01.ply"}) {
    EXPECT_TRUE(fs::exists(tmp / "out" / f)) << f;
  }
  EXPECT_FALSE(fs::exists(tmp / "out" / "alert_02.ply"));
  // At the second session: one session of history, in the singular.
  r = test::runCommand(cli() + " alerts " + m + " --at 2012-03-05T20:00:00Z --min-voxels 5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("1 changed object at 2012-03-05T20:00:00Z"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("; 1 session of history)"), std::string::npos) << r.out;
  // Bad input: one line naming what is wrong.
  writeFileAtomic(tmp / "bad.cmap", std::vector<uint8_t>{'n', 'o', 'p', 'e'});
  const std::pair<std::string, std::string> bad[] = {
      {m + " --at 2012-03-11T10:00:00Z", "no session of the map lies at 2012-03-11T10:00:00"},
      {m + " --at 2012-03-05T09:00:00Z", "first session"},
      {m + " --at never", "neither ISO-8601"},
      {(tmp / "bad.cmap").string() + " --at 2012-03-11T09:00:00Z", "bad.cmap"},
      {(tmp / "missing.cmap").string() + " --at 2012-03-11T09:00:00Z", "missing.cmap"},
      {m + " --at 2012-03-11T09:00:00Z --neighbourhood 9", "--neighbourhood"},
  };
  for (const auto& [args, message] : bad) {
    r = test::runCommand(cli() + " alerts " + args);
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

/// A 4D map with colour changes: an 8 x 8 wall lit by lamps by day and a warm sun at 19:00, three
/// sessions a day (09:00, 13:00, 19:00) for five days; the last session repaints the columns x < 3.
/// Also a voxel that comes and goes, so that the occupancy has something to model.
std::vector<double> writeLitWall(const fs::path& path, double colour_distance) {
  TemporalMap map(0.05, ChangeCriterion{0.0, colour_distance});
  std::vector<double> times;
  const double hours[] = {9.0, 13.0, 19.0};
  const double light[3][3] = {{0.8, 0.8, 0.75}, {1.0, 1.0, 1.0}, {0.9, 0.55, 0.3}};
  for (int d = 0; d < 5; ++d) {
    for (int k = 0; k < 3; ++k) {
      const bool repaint = d == 4 && k == 2;
      SessionMap s(0.05);
      for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
          const double albedo[3] = {120.0 + 10 * x, 100.0 + 8 * y, 90.0};
          const double paint[3] = {40.0, 160.0, 60.0};
          const double* a = repaint && x < 3 ? paint : albedo;
          VoxelCounters c;
          c.length_m = 0.1f;
          c.hits = 4;
          c.red = 4 * static_cast<uint32_t>(std::lround(a[0] * light[k][0]));
          c.green = 4 * static_cast<uint32_t>(std::lround(a[1] * light[k][1]));
          c.blue = 4 * static_cast<uint32_t>(std::lround(a[2] * light[k][2]));
          s.add(at(x, y, 0), c);
        }
      }
      s.add(at(12, 12, 0), (d + k) % 2 ? occupied() : freeVoxel());
      const double t = 1330905600.0 + 86400.0 * d + 3600.0 * hours[k];
      map.add(t, s);
      times.push_back(t);
    }
  }
  writeTemporalMap(path, map, {});
  return times;
}

/// `a`'s 4D map with its first session replaced by the wall one voxel further along x: the same
/// sessions' times and resolution, another map.
void writeShiftedFirstSession(const fs::path& a, const fs::path& b) {
  TemporalMap map = readTemporalMap(a);
  SessionMap shifted(0.05);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) shifted.add(at(x + 1, y, 0), occupied());
  }
  map.add(map.times().front(), shifted, AddSettings{true, "shifted"});
  writeTemporalMap(b, map, {});
}

TEST(AnalysisCli, SavedModelsAreRefusedOnAnotherMap) {
  test::TempDir tmp;
  writeLitWall(tmp / "a.cmap", 4.0);
  writeShiftedFirstSession(tmp / "a.cmap", tmp / "b.cmap");
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string();
  const std::string rhythm = (tmp / "a.rhythm").string(), colour = (tmp / "a.colour").string();
  const std::string when = " --at 2012-03-12T19:00:00Z ", band = " --z-min -1 --z-max 1 ";
  // (view serves until stopped once its model passes: a time limit keeps a missed refusal from hanging.)
  auto run = [&](const std::string& args) { return test::runCommand("timeout 30 " + cli() + " " + args); };
  // Fitted on a and saved; used on a again: accepted without a word on stderr.
  auto r = run("predict " + a + when + "--save-rhythm " + rhythm + " --save-colour " + colour + " -o " +
               (tmp / "fit.png").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run("predict " + a + when + "--rhythm " + rhythm + " --colour-model " + colour + " -o " + (tmp / "p.png").string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  r = run("costmap " + a + when + band + "--rhythm " + rhythm + " -o " + (tmp / "c.yaml").string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  // view: the model passes; only the address (not one of this machine) stops it.
  r = run("view " + a + " --rhythm " + rhythm + " --host 203.0.113.1 --port 1");
  EXPECT_NE(r.err.find("cannot listen on 203.0.113.1"), std::string::npos) << r.err;

  // On b (same times, other voxels): refused by predict, costmap and view, in one line naming
  // both files, what differs and the way out; nothing written.
  const std::string out = (tmp / "x.png").string();
  const std::pair<std::string, std::string> refused[] = {
      {"predict " + b + when + "--rhythm " + rhythm + " -o " + out, "a.rhythm: the rhythm model was fitted on another map"},
      {"predict " + b + when + "--colour-model " + colour + " -o " + out, "a.colour: the colour model was fitted on another map"},
      {"costmap " + b + when + band + "--rhythm " + rhythm + " -o " + (tmp / "x.yaml").string(),
       "a.rhythm: the rhythm model was fitted on another map"},
      {"view " + b + " --rhythm " + rhythm + " --port 0", "a.rhythm: the rhythm model was fitted on another map"},
  };
  for (const auto& [args, message] : refused) {
    r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << ": " << r.err;
    EXPECT_NE(r.err.find("15 sessions from 2012-03-05T09:00:00Z to 2012-03-09T19:00:00Z"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("observed other voxels"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("b.cmap has 15 sessions"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("or pass --allow-other-map to use it anyway"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(tmp / "x.yaml"));
  // --allow-other-map: used, with the same facts as a warning.
  r = run("predict " + b + when + "--rhythm " + rhythm + " --colour-model " + colour + " --allow-other-map -o " + out);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("chronomap: warning: " + rhythm + ": the rhythm model was fitted on another map"),
            std::string::npos) << r.err;
  EXPECT_NE(r.err.find("used anyway, as --allow-other-map asks"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 2) << r.err;  // the rhythm and the colour model

  // A model saved before the fingerprint (.rhythm version 3) cannot be checked beyond its
  // resolution and learning range: used with a warning that says so.
  const std::string old = (tmp / "old.rhythm").string();
  writeFileAtomic(old, serialize(readRhythmModels(rhythm), 3));
  for (const std::string& map : {a, b}) {
    r = run("predict " + map + when + "--rhythm " + old + " -o " + (tmp / "o.png").string());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("chronomap: warning: " + old + ": the rhythm model records no fingerprint of the map"),
              std::string::npos) << r.err;
  }
  // ... and refused on a map without its first or last learning session.
  TemporalMap later = readTemporalMap(a);
  later.remove(later.times().front());
  writeTemporalMap(tmp / "later.cmap", later, {});
  r = run("predict " + (tmp / "later.cmap").string() + when + "--rhythm " + old + " -o " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("later.cmap has no session at 2012-03-05T09:00:00Z"), std::string::npos) << r.err;
}

TEST(AnalysisCli, ColourPredictionAndLightingInvariantDiff) {
  test::TempDir tmp;
  const std::vector<double> times = writeLitWall(tmp / "m.cmap", 4.0);
  const std::string m = (tmp / "m.cmap").string();
  auto ref = [&](size_t i) { return m + "@" + std::to_string(static_cast<int64_t>(times[i])); };
  // predict --colour: a PLY coloured at 19:00 of a later day.
  const auto p = test::runCommand(cli() + " predict " + m + " --at 2012-03-12T19:00:00Z --colour -o " +
                                  (tmp / "p.ply").string() + " --json");
  ASSERT_EQ(p.exit_code, 0) << p.err;
  const auto pj = nlohmann::json::parse(p.out);
  EXPECT_EQ(pj["colour"]["voxels"], 65);  // the wall and the voxel that comes and goes
  EXPECT_DOUBLE_EQ(pj["colour"]["hour"].get<double>(), 19.0);
  EXPECT_EQ(pj["colour"]["bytes_per_voxel"], 30);
  EXPECT_TRUE(fs::exists(tmp / "p.ply"));
  // --save-colour keeps the model; --colour-model predicts the same colours without refitting.
  const std::string model = (tmp / "wall.colour").string();
  const auto saved = test::runCommand(cli() + " predict " + m + " --at 2012-03-12T19:00:00Z --save-colour " + model +
                                      " -o " + (tmp / "s.ply").string() + " --json");
  ASSERT_EQ(saved.exit_code, 0) << saved.err;
  EXPECT_EQ(nlohmann::json::parse(saved.out)["colour"], pj["colour"]);
  const auto loaded = test::runCommand(cli() + " predict " + m + " --at 2012-03-12T19:00:00Z --colour-model " + model +
                                       " -o " + (tmp / "l.ply").string() + " --json");
  ASSERT_EQ(loaded.exit_code, 0) << loaded.err;
  EXPECT_EQ(nlohmann::json::parse(loaded.out)["colour"], pj["colour"]);
  EXPECT_EQ(test::bytesOf(tmp / "l.ply"), test::bytesOf(tmp / "p.ply"));
  // A saved model takes no learning range; a truncated one is refused with one clear line.
  const auto ranged = test::runCommand(cli() + " predict " + m + " --at 2012-03-12T19:00:00Z --colour-model " + model +
                                       " --learn-to 2012-03-08T00:00:00Z -o " + (tmp / "r.ply").string());
  EXPECT_EQ(ranged.exit_code, 2);
  EXPECT_NE(ranged.err.find("--colour-model reads a fitted model"), std::string::npos) << ranged.err;
  fs::resize_file(model, fs::file_size(model) - 3);
  const auto cut = test::runCommand(cli() + " predict " + m + " --at 2012-03-12T19:00:00Z --colour-model " + model +
                                    " -o " + (tmp / "c.ply").string());
  EXPECT_EQ(cut.exit_code, 1);
  EXPECT_NE(cut.err.find("wall.colour: the colour model ends early (truncated)"), std::string::npos) << cut.err;
  // The 13:00 -> 19:00 light of day 3: every colour moves, the light explains all of it.
  auto diff = [&](size_t a, size_t b, const std::string& flags) {
    const auto r = test::runCommand(cli() + " diff " + ref(a) + " " + ref(b) + " -o " + (tmp / "d.cmap").string() +
                                    " --json " + flags);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.exit_code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json{};
  };
  const auto plain = diff(10, 11, "--colour 20");
  EXPECT_EQ(plain["colour_compared"], 64);
  EXPECT_EQ(plain["colour_changed"], 64);
  EXPECT_EQ(diff(10, 11, "--colour 20 --lighting-invariant")["colour_changed"], 0);
  // The last day's 13:00 -> 19:00 with the repaint: the 24 repainted voxels only.
  EXPECT_EQ(diff(13, 14, "--colour 20 --lighting-invariant")["colour_changed"], 24);
  // Bad input: no colour in the map, --lighting-invariant alone, session maps, a time before the map.
  writeLitWall(tmp / "plain.cmap", 0.0);
  const auto none = test::runCommand(cli() + " predict " + (tmp / "plain.cmap").string() +
                                     " --at 2012-03-12T19:00:00Z --colour -o " + (tmp / "q.ply").string());
  EXPECT_NE(none.exit_code, 0);
  EXPECT_NE(none.err.find("--color-distance"), std::string::npos) << none.err;
  const auto alone = test::runCommand(cli() + " diff " + ref(10) + " " + ref(11) + " --lighting-invariant -o " +
                                      (tmp / "e.cmap").string());
  EXPECT_NE(alone.exit_code, 0);
  EXPECT_NE(alone.err.find("--colour"), std::string::npos) << alone.err;
  writePair(tmp / "a.cmap", tmp / "b.cmap");
  const auto sessions = test::runCommand(cli() + " diff " + (tmp / "a.cmap").string() + " " + (tmp / "b.cmap").string() +
                                         " --colour 20 -o " + (tmp / "f.cmap").string());
  EXPECT_NE(sessions.exit_code, 0);
  EXPECT_NE(sessions.err.find("MAP.cmap@TIME"), std::string::npos) << sessions.err;
  const auto early = test::runCommand(cli() + " diff " + m + "@2012-03-01T00:00:00Z " + ref(11) +
                                      " --colour 20 --lighting-invariant -o " + (tmp / "g.cmap").string());
  EXPECT_NE(early.exit_code, 0);
  EXPECT_NE(early.err.find("before"), std::string::npos) << early.err;
}

}  // namespace
}  // namespace chronomap
