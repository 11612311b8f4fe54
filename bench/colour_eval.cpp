// Colour by time of day (issue 23, part 3): what keeping colour changes costs in the 4D map, how
// well the colour model predicts each surface's colour at a held-out session's hour, and how many
// false colour changes a diff reports at sunset with and without the lighting-invariant test.
//
// Usage: colour_eval [--weeks DIR] [--floor66 DIR] [--scale S] [--learn-days D] [--distance D]
//   --seeds A-B    simulate seeds A to B (with --sensor NAME, through that sensor) and run once on each;
//                  prints every figure's mean, min and max (seeds.h). Train on 1-5, report 6-15.
//                    [--diff-distance D] [--components K] [--out DIR]
//   --weeks DIR      a `chronomap simulate --preset weeks --lighting daylight --repaint` output
//                    (default: simulated here at --scale into a temporary folder)
//   --floor66 DIR    a `chronomap simulate --preset floor66` output, for the storage cost only
//                    (default: none, the floor66 rows are left out)
//   --scale S        image size of the simulation made here (default 0.25)
//   --sensor NAME  ideal (default), kinect or realsense: the sensor of the simulations made here
//                  (SimulationSettings::sensor); a folder given keeps its own
//   --learn-days D   days of history (default 21: three weeks; the last week tests)
//   --distance D     the 4D map's colour distance for the model (default 10)
//   --diff-distance  colour distance of the diff (default 30)
//   --components K   light curves of the model (default 2)
//   --bins B         knots per day of each curve (default 24)
//   --out DIR        top views (observed, predicted, latest) at the test sessions nearest 09:30
//                    and 20:30 (observed_morning.png, ...), for the docs' picture
// Sessions are integrated with their true poses (groundtruth.txt), fast mode at 0.05 m, so that
// colour errors are the model's, not the registration's. Last line: one JSON object.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_sim.h"
#include "seeds.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/core/time.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/maps.h"

namespace fs = std::filesystem;
using namespace chronomap;

namespace {

struct Sessions {
  std::vector<SessionMap> maps;
  std::vector<double> times;
  nlohmann::json scene;
};

Sessions integrateAll(const fs::path& dir) {
  Sessions s;
  s.scene = nlohmann::json::parse(readTextFile(dir / "scene.json"));
  for (const auto& j : s.scene["sessions"]) {
    const fs::path p = dir / j["dir"].get<std::string>();
    SessionSettings ss = bench::simSessionSettings();
    ss.dataset.trajectory = p / "groundtruth.txt";
    s.maps.push_back(integrateDataset(p, ss).map);
    s.times.push_back(j["time_s"].get<double>());
    std::fprintf(stderr, "\r  integrated %zu/%zu sessions", s.maps.size(), s.scene["sessions"].size());
  }
  std::fprintf(stderr, "\n");
  return s;
}

TemporalMap buildMap(const Sessions& s, double colour_distance, size_t sessions) {
  TemporalMap m(0.05, ChangeCriterion{0.0, colour_distance});
  for (size_t i = 0; i < sessions; ++i) m.add(s.times[i], s.maps[i]);
  return m;
}

struct Cost {
  double distance;
  size_t nodes, entries;
  uint64_t bytes;
};

Cost measure(const Sessions& s, double d, const fs::path& scratch) {
  const TemporalMap m = buildMap(s, d, s.maps.size());
  writeTemporalMap(scratch, m, {{"created_by", "colour_eval"}});
  const Cost c{d, m.counts().nodes(), m.counts().entries, fs::file_size(scratch)};
  fs::remove(scratch);
  return c;
}

std::vector<Cost> costTable(const char* name, const Sessions& s, const fs::path& scratch) {
  std::vector<Cost> costs;
  std::printf("\n%s (%zu sessions): the 4D map with and without colour changes\n", name, s.maps.size());
  std::printf("| --color-distance | nodes | entries | file bytes | nodes vs off | bytes vs off | bytes per session |\n"
              "|---:|---:|---:|---:|---:|---:|---:|\n");
  for (double d : {0.0, 40.0, 20.0, 10.0, 5.0}) {
    costs.push_back(measure(s, d, scratch));
    const Cost& c = costs.back();
    std::printf("| %s | %zu | %zu | %llu | %+.1f%% | %+.1f%% | %.0f |\n", d == 0.0 ? "off" : std::to_string(int(d)).c_str(),
                c.nodes, c.entries, static_cast<unsigned long long>(c.bytes),
                100.0 * (double(c.nodes) / double(costs[0].nodes) - 1.0),
                100.0 * (double(c.bytes) / double(costs[0].bytes) - 1.0), double(c.bytes) / double(s.maps.size()));
    std::fflush(stdout);
  }
  return costs;
}

double rgbDistance(const std::array<double, 3>& a, const Rgb& b) {
  const double dr = a[0] - b.r, dg = a[1] - b.g, db = a[2] - b.b;
  return std::sqrt(dr * dr + dg * dg + db * db);
}

std::array<double, 3> clamp255(std::array<double, 3> a) {
  for (double& x : a) x = std::clamp(x, 0.0, 255.0);
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  {  // --seeds A-B: this program once per simulated seed, and the spread of its figures (seeds.h)
    SimulationSettings s;
    s.preset = "weeks";
    s.resolution_scale = 0.25;
    s.lighting = "daylight";
    s.repaint = true;
    if (const int rc = bench::runOverSeeds(argc, argv, "--weeks", s); rc >= 0) return rc;
  }
  std::string weeks_dir, floor_dir, out_dir;
  double scale = 0.25, distance = 10.0, diff_distance = 30.0;
  int learn_days = 21, components = 2, bins = 24;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return bench::argValue(i, argc, argv); };
    if (a == "--weeks") weeks_dir = value();
    else if (a == "--floor66") floor_dir = value();
    else if (a == "--scale") scale = std::stod(value());
    else if (a == "--learn-days") learn_days = std::stoi(value());
    else if (a == "--distance") distance = std::stod(value());
    else if (a == "--diff-distance") diff_distance = std::stod(value());
    else if (a == "--components") components = std::stoi(value());
    else if (a == "--bins") bins = std::stoi(value());
    else if (a == "--out") out_dir = value();
    else if (a == "--sensor") bench::setSimSensor(value());
    else {
      std::fprintf(stderr, "usage: colour_eval [--weeks DIR] [--floor66 DIR] [--scale S] [--learn-days D] "
                           "[--distance D] [--diff-distance D] [--components K] [--bins B] [--out DIR] "
                           "[--sensor ideal|kinect|realsense]\n");
      return 2;
    }
  }
  const fs::path tmp = fs::temp_directory_path() / ("colour_eval_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  const fs::path scratch = tmp / "map.cmap";
  nlohmann::json result;

  if (!floor_dir.empty()) {
    const auto t0 = std::chrono::steady_clock::now();
    const Sessions floor = integrateAll(floor_dir);
    const std::vector<Cost> costs = costTable("floor66", floor, scratch);
    for (const Cost& c : costs) {
      if (c.distance == distance) {
        result["floor66_bytes_increase"] = double(c.bytes) / double(costs[0].bytes) - 1.0;
        result["floor66_nodes_increase"] = double(c.nodes) / double(costs[0].nodes) - 1.0;
      }
    }
    std::printf("floor66: %.0f s\n", bench::seconds(t0));
  }

  if (weeks_dir.empty()) {
    SimulationSettings s;
    s.preset = "weeks";
    s.resolution_scale = scale;
    s.lighting = "daylight";
    s.repaint = true;
    s.sensor = bench::simSensor();
    std::printf("simulating the weeks preset at %.2f of 640x480 with daylight and a repaint (%s sensor) ...\n", scale,
                s.sensor.c_str());
    std::fflush(stdout);
    chronomap::simulate(s, tmp / "weeks");
    weeks_dir = (tmp / "weeks").string();
  }
  const auto t0 = std::chrono::steady_clock::now();
  const Sessions weeks = integrateAll(weeks_dir);
  if (!weeks.scene.contains("lighting") || !weeks.scene.contains("repaints")) {
    std::fprintf(stderr, "%s was simulated without --lighting daylight --repaint\n", weeks_dir.c_str());
    return 2;
  }
  const std::vector<Cost> costs = costTable("weeks (daylight)", weeks, scratch);
  Cost chosen = costs[0];
  for (const Cost& c : costs) {
    if (c.distance == distance) chosen = c;
  }

  // The split: learn from the first `learn_days` days, test on the rest.
  const double split_s = kScheduleStart_s + 86400.0 * learn_days;
  std::vector<size_t> test;
  for (size_t i = 0; i < weeks.times.size(); ++i) {
    if (weeks.times[i] >= split_s) test.push_back(i);
  }
  const TemporalMap map = buildMap(weeks, distance, weeks.maps.size());
  const double last_learn = weeks.times[test.front() - 1];
  ColourSettings cs;
  cs.components = components;
  cs.bins = bins;
  const auto fit_start = std::chrono::steady_clock::now();
  const ColourData data = colourObservations(map, -1e300, last_learn);
  ColourModel model = fitColourObservations(data.observations, data.keys.size(), cs);
  model.keys = data.keys;
  const double fit_s = bench::seconds(fit_start);
  // The mean colour baseline: each voxel's learning observations averaged.
  std::vector<std::array<double, 3>> mean(data.keys.size(), {0, 0, 0});
  std::vector<double> count(data.keys.size(), 0.0);
  for (const ColourObservation& o : data.observations) {
    for (size_t c = 0; c < 3; ++c) mean[o.voxel][c] += o.rgb[c];
    count[o.voxel] += 1;
  }
  for (size_t v = 0; v < mean.size(); ++v) {
    for (double& x : mean[v]) x /= std::max(count[v], 1.0);
  }
  std::printf("\ncolour model: %zu voxels, %zu observations from %zu sessions, %d light curve(s), fit RMS %.2f per "
              "channel, %zu bytes (%zu per voxel), fitted in %.1f s\n",
              model.keys.size(), data.observations.size(), data.sessions, components, model.rms_error, model.bytes(),
              model.bytesPerVoxel(), fit_s);

  // The truth voxels of every change after the split (routines, the repaint): not "stayed put".
  std::set<uint64_t> moved;
  for (const auto& e : weeks.scene["events"]) {
    if (e["to_session"].get<size_t>() < test.front()) continue;
    for (const auto& k : e["voxels"]) moved.insert(mortonEncode(VoxelKey{k[0].get<uint16_t>(), k[1].get<uint16_t>(), k[2].get<uint16_t>()}));
  }
  std::set<uint64_t> repainted;
  for (const auto& r : weeks.scene["repaints"]) {
    for (const auto& k : r["voxels"]) repainted.insert(mortonEncode(VoxelKey{k[0].get<uint16_t>(), k[1].get<uint16_t>(), k[2].get<uint16_t>()}));
  }
  auto nearChange = [&](const VoxelKey& k, const std::set<uint64_t>& set) {
    // The voxel or one of its 26 neighbours (a surface voxel of a moved object may lie a voxel out).
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const VoxelKey n{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy), static_cast<uint16_t>(k.z + dz)};
          if (set.count(mortonEncode(n))) return true;
        }
      }
    }
    return false;
  };

  // Prediction error at each test session's hour, on voxels occupied with hits both in the test
  // session and in the map at the end of learning (a surface that stayed put), the repainted
  // desk and every truth change left out.
  const SessionMap latest_map = map.snapshot(last_learn);
  double err_model = 0, err_mean = 0, err_latest = 0;
  size_t n = 0;
  std::printf("\n| test session | time | hour | voxels | model | mean colour | latest colour |\n|---:|---|---:|---:|---:|---:|---:|\n");
  for (size_t i : test) {
    const double hour = hourOfDay(weeks.times[i]);
    double em = 0, en = 0, el = 0;
    size_t k = 0;
    weeks.maps[i].forEachLeaf([&](const LeafView& leaf) {
      if (leaf.level != 0 || leaf.counters.hits == 0 || leaf.counters.state() != VoxelState::Occupied) return;
      const auto v = model.find(leaf.key);
      if (!v) return;
      const auto last = latest_map.find(leaf.key);
      if (!last || last->hits == 0 || last->state() != VoxelState::Occupied) return;
      if (nearChange(leaf.key, moved) || nearChange(leaf.key, repainted)) return;
      const Rgb observed = leaf.counters.meanColour();
      em += rgbDistance(clamp255(model.predict(*v, hour)), observed);
      en += rgbDistance(mean[*v], observed);
      const Rgb l = last->meanColour();
      el += rgbDistance({double(l.r), double(l.g), double(l.b)}, observed);
      ++k;
    });
    std::printf("| %zu | %s | %.1f | %zu | %.1f | %.1f | %.1f |\n", i, formatTime(weeks.times[i]).c_str(), hour, k,
                em / std::max<size_t>(k, 1), en / std::max<size_t>(k, 1), el / std::max<size_t>(k, 1));
    err_model += em;
    err_mean += en;
    err_latest += el;
    n += k;
  }
  err_model /= double(std::max<size_t>(n, 1));
  err_mean /= double(std::max<size_t>(n, 1));
  err_latest /= double(std::max<size_t>(n, 1));
  std::printf("\nmean colour error (8-bit RGB distance) over %zu voxel observations: model %.1f, mean colour %.1f, latest "
              "colour %.1f\n",
              n, err_model, err_mean, err_latest);

  // Diffs between consecutive sessions of the test days: false colour changes (voxels flagged
  // that no truth change or repaint explains), with and without the lighting-invariant test; the
  // repaint found. Sunset pairs: the later session between 17:00 and 21:00.
  ColourDiffSettings raw;
  raw.distance = diff_distance;
  ColourDiffSettings inv = raw;
  inv.lighting_invariant = true;
  struct Tally {
    size_t pairs = 0, compared = 0, false_raw = 0, false_inv = 0;
  } sunset, all;
  std::printf("\n| pair | hours | compared | false changes, plain | false changes, lighting-invariant |\n"
              "|---|---|---:|---:|---:|\n");
  for (size_t i = std::max<size_t>(test.front(), 1); i <= test.back(); ++i) {
    const double t1 = weeks.times[i - 1], t2 = weeks.times[i];
    const ColourDiff a = colourChanges(map, t1, t2, &model, raw), b = colourChanges(map, t1, t2, &model, inv);
    size_t fa = 0, fb = 0;
    // Changes the truth explains: objects that moved between the two sessions.
    std::set<uint64_t> moved_now;
    for (const auto& e : weeks.scene["events"]) {
      if (e["to_session"].get<size_t>() != i) continue;
      for (const auto& k : e["voxels"]) moved_now.insert(mortonEncode(VoxelKey{k[0].get<uint16_t>(), k[1].get<uint16_t>(), k[2].get<uint16_t>()}));
    }
    for (const ColourChange& c : a.changes) fa += !nearChange(c.key, moved_now) && !nearChange(c.key, repainted);
    for (const ColourChange& c : b.changes) fb += !nearChange(c.key, moved_now) && !nearChange(c.key, repainted);
    const double h2 = hourOfDay(t2);
    const bool is_sunset = h2 >= 17.0 && h2 < 21.0;
    for (Tally* t : {&all, is_sunset ? &sunset : nullptr}) {
      if (!t) continue;
      ++t->pairs;
      t->compared += a.compared;
      t->false_raw += fa;
      t->false_inv += fb;
    }
    std::printf("| %zu-%zu | %.1f -> %.1f%s | %zu | %zu | %zu |\n", i - 1, i, hourOfDay(t1), h2,
                is_sunset ? " (sunset)" : "", a.compared, fa, fb);
  }
  std::printf("\nfalse colour changes per pair (colour distance %.0f): sunset pairs (%zu): plain %.1f, lighting-invariant "
              "%.1f; all test pairs (%zu): plain %.1f, lighting-invariant %.1f\n",
              diff_distance, sunset.pairs, double(sunset.false_raw) / std::max<size_t>(sunset.pairs, 1),
              double(sunset.false_inv) / std::max<size_t>(sunset.pairs, 1), all.pairs,
              double(all.false_raw) / std::max<size_t>(all.pairs, 1), double(all.false_inv) / std::max<size_t>(all.pairs, 1));

  // The repaint: the last session before it against the first later session that observed the
  // table again (its voxels with an entry stored after the repaint): how many of those the diff
  // finds, and its false changes there (voxels no truth change or repaint explains).
  const size_t repaint_session = weeks.scene["repaints"][0]["to_session"].get<size_t>();
  size_t repaint_voxels = 0, repaint_found_raw = 0, repaint_found_inv = 0, repaint_false_raw = 0, repaint_false_inv = 0;
  size_t repaint_seen_at = 0;
  for (size_t i = repaint_session; i < weeks.times.size() && repaint_voxels == 0; ++i) {
    std::set<uint64_t> seen_again;
    map.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
      if (level != 0 || !repainted.count(mortonEncode(corner))) return;
      for (const TemporalMap::Entry& e : entries) {
        if (e.session >= repaint_session && e.session <= i && e.value.hits > 0) seen_again.insert(mortonEncode(corner));
      }
    });
    if (seen_again.empty()) continue;
    std::set<uint64_t> moved_between;
    for (const auto& e : weeks.scene["events"]) {
      const size_t to = e["to_session"].get<size_t>();
      if (to < repaint_session || to > i) continue;
      for (const auto& k : e["voxels"]) moved_between.insert(mortonEncode(VoxelKey{k[0].get<uint16_t>(), k[1].get<uint16_t>(), k[2].get<uint16_t>()}));
    }
    const double t1 = weeks.times[repaint_session - 1], t2 = weeks.times[i];
    const ColourDiff a = colourChanges(map, t1, t2, &model, raw), b = colourChanges(map, t1, t2, &model, inv);
    auto tally = [&](const ColourDiff& d, size_t& found, size_t& wrong) {
      for (const ColourChange& c : d.changes) {
        if (seen_again.count(mortonEncode(c.key))) ++found;
        else if (!nearChange(c.key, moved_between) && !nearChange(c.key, repainted)) ++wrong;
      }
    };
    tally(a, repaint_found_raw, repaint_false_raw);
    tally(b, repaint_found_inv, repaint_false_inv);
    repaint_voxels = seen_again.size();
    repaint_seen_at = i;
    std::printf("\nthe repaint (session %zu): sessions %zu (%.1f h) -> %zu (%.1f h), the first to see the desk again: "
                "%zu repainted voxels seen again; found plain %zu, lighting-invariant %zu; false changes plain %zu, "
                "lighting-invariant %zu\n",
                repaint_session, repaint_session - 1, hourOfDay(t1), i, hourOfDay(t2), repaint_voxels, repaint_found_raw,
                repaint_found_inv, repaint_false_raw, repaint_false_inv);
  }

  if (!out_dir.empty()) {
    // Top views at the test sessions nearest 08:00 and 20:00: observed, predicted, latest colour.
    fs::create_directories(out_dir);
    for (double want : {9.5, 20.5}) {
      size_t best = test.front();
      for (size_t i : test) {
        if (std::abs(hourOfDay(weeks.times[i]) - want) < std::abs(hourOfDay(weeks.times[best]) - want)) best = i;
      }
      const std::string tag = want < 12.0 ? "morning" : "evening";
      exportSessionMap(fs::path(out_dir) / ("observed_" + tag + ".png"), weeks.maps[best]);
      exportSessionMap(fs::path(out_dir) / ("predicted_" + tag + ".png"),
                                 recolour(weeks.maps[best], model, weeks.times[best]));
      exportSessionMap(fs::path(out_dir) / ("latest_" + tag + ".png"), latest_map);
      std::printf("top views at session %zu (%s, hour %.2f) in %s\n", best, formatTime(weeks.times[best]).c_str(),
                  hourOfDay(weeks.times[best]), out_dir.c_str());
    }
  }
  std::printf("weeks: %.0f s\n", bench::seconds(t0));
  fs::remove_all(tmp);

  result["colour_distance"] = distance;
  result["colour_components"] = components;
  result["colour_bins"] = bins;
  result["colour_error_model"] = err_model;
  result["colour_error_mean"] = err_mean;
  result["colour_error_latest"] = err_latest;
  result["colour_model_bytes_per_voxel"] = model.bytesPerVoxel();
  result["colour_model_voxels"] = model.keys.size();
  result["colour_bytes_per_session"] = (double(chosen.bytes) - double(costs[0].bytes)) / double(weeks.maps.size());
  result["weeks_bytes_increase"] = double(chosen.bytes) / double(costs[0].bytes) - 1.0;
  result["weeks_nodes_increase"] = double(chosen.nodes) / double(costs[0].nodes) - 1.0;
  result["diff_false_changes_sunset_plain"] = double(sunset.false_raw) / std::max<size_t>(sunset.pairs, 1);
  result["diff_false_changes_sunset_invariant"] = double(sunset.false_inv) / std::max<size_t>(sunset.pairs, 1);
  result["diff_false_changes_plain"] = double(all.false_raw) / std::max<size_t>(all.pairs, 1);
  result["diff_false_changes_invariant"] = double(all.false_inv) / std::max<size_t>(all.pairs, 1);
  result["repaint_voxels"] = repaint_voxels;
  result["repaint_found_plain"] = repaint_found_raw;
  result["repaint_found_invariant"] = repaint_found_inv;
  result["repaint_false_plain"] = repaint_false_raw;
  result["repaint_false_invariant"] = repaint_false_inv;
  result["repaint_seen_again_session"] = repaint_seen_at;
  std::printf("%s\n", result.dump().c_str());
  return 0;
}
