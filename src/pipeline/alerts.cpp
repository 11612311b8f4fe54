#include "chronomap/pipeline/alerts.h"

#include <algorithm>
#include <cstdio>

#include "chronomap/analysis/changes.h"
#include "chronomap/core/time.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/export/export.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "chronomap/render/top_view.h"
#include "json_vec.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

using pipeline_detail::vec3;

size_t count(const AlertReport& report, size_t top) {
  return top == 0 ? report.alerts.size() : std::min(top, report.alerts.size());
}

/// The diff of the given components' cells and each component re-indexed into it, its id set
/// to its rank (1..).
std::pair<DiffMap, Segmentation> ranked(const AlertReport& report, size_t n) {
  std::vector<uint32_t> used;
  for (size_t i = 0; i < n; ++i) {
    used.insert(used.end(), report.alerts[i].component.cells.begin(), report.alerts[i].component.cells.end());
  }
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  std::vector<ChangeCell> cells;
  cells.reserve(used.size());
  for (uint32_t i : used) cells.push_back(report.diff.cells()[i]);
  DiffMap d = DiffMap::fromCells(report.diff.resolution_m(), report.diff.settings(), std::move(cells));
  Segmentation seg;
  for (size_t i = 0; i < n; ++i) {
    Component c = report.alerts[i].component;
    c.id = static_cast<uint32_t>(i + 1);
    for (uint32_t& cell : c.cells) {
      cell = static_cast<uint32_t>(std::lower_bound(used.begin(), used.end(), cell) - used.begin());
    }
    seg.components.push_back(std::move(c));
  }
  return {std::move(d), std::move(seg)};
}

/// The part of `map` whose x, y lie within `margin_m` of the box.
SessionMap crop(const SessionMap& map, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double margin_m) {
  SessionMap out(map.resolution_m());
  const KeyGrid& g = map.grid();
  map.forEachLeaf([&](const LeafView& leaf) {
    const Eigen::Vector3d p = g.centerOf(leaf.key);
    if (p.x() < lo.x() - margin_m || p.x() > hi.x() + margin_m || p.y() < lo.y() - margin_m ||
        p.y() > hi.y() + margin_m) {
      return;
    }
    if (leaf.level == 0) out.assign(leaf.key, leaf.counters);
  });
  return out;
}

}  // namespace

namespace {

/// The changed objects (findChanges' list, as `chronomap diff --json` prints it), most unusual
/// first: each with the score of its component (a move: of its halves, which pairing made equal),
/// its rank and its reason; the `top` first (0: all).
nlohmann::json rankedObjectsJson(const AlertReport& report, size_t top) {
  const nlohmann::json objects = changedObjectsJson(report.objects);
  std::vector<std::pair<size_t, const Alert*>> ranked;  // object index, its highest-scored alert
  for (size_t i = 0; i < report.objects.size(); ++i) {
    const Alert* best = nullptr;
    for (const Alert& a : report.alerts) {
      const auto& ids = report.objects[i].components;
      if (std::find(ids.begin(), ids.end(), a.component.id) == ids.end()) continue;
      if (!best || a.score_bits > best->score_bits) best = &a;
    }
    if (best) ranked.push_back({i, best});
  }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const auto& x, const auto& y) { return x.second->score_bits > y.second->score_bits; });
  nlohmann::json list = nlohmann::json::array();
  for (size_t r = 0; r < ranked.size() && (top == 0 || r < top); ++r) {
    nlohmann::json o = objects[ranked[r].first];
    o["rank"] = r + 1;
    o["score_bits"] = ranked[r].second->score_bits;
    o["probability"] = ranked[r].second->probability;
    o["reason"] = ranked[r].second->reason;
    list.push_back(std::move(o));
  }
  return list;
}

}  // namespace

nlohmann::json alertsJson(const AlertReport& report, size_t top) {
  nlohmann::json list = nlohmann::json::array();
  const size_t n = count(report, top);
  for (size_t i = 0; i < n; ++i) {
    const Alert& a = report.alerts[i];
    const Component& c = a.component;
    list.push_back({{"rank", i + 1},
                    {"score_bits", a.score_bits},
                    {"probability", a.probability},
                    {"reason", a.reason},
                    {"own_score_bits", a.own_score_bits},
                    {"moved_with", a.moved_with},
                    {"id", c.id},
                    {"kind", toString(c.kind)},
                    {"voxels", c.voxels},
                    {"volume_m3", c.volume_m3},
                    {"centroid", vec3(c.centroid_m)},
                    {"bbox_min", vec3(c.bbox_min_m)},
                    {"bbox_max", vec3(c.bbox_max_m)},
                    {"mean_color", {c.mean_colour.r, c.mean_colour.g, c.mean_colour.b}},
                    {"evidence",
                     {{"observations", a.evidence.observations},
                      {"in_new_state", a.evidence.in_state},
                      {"window_observations", a.evidence.window_observations},
                      {"window_in_new_state", a.evidence.window_in_state},
                      {"neighbour_distance_voxels", a.neighbour_distance_voxels}}}});
  }
  return {{"time", formatTime(report.time_s)},
          {"time_s", report.time_s},
          {"previous", formatTime(report.previous_time_s)},
          {"history_sessions", report.history_sessions},
          {"objects", rankedObjectsJson(report, top)},
          {"components", report.alerts.size()},
          {"dropped_small", report.segmentation.dropped},
          {"changed_voxels", report.diff.voxelCount()},
          {"alerts", list}};
}

void writeAlerts(const fs::path& folder, const TemporalMap& map, const AlertReport& report, size_t top,
                 const std::string& source) {
  const size_t n = count(report, top);
  std::vector<std::string> names = {"alerts.json", "alerts.png"};
  for (size_t i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "alert_%02zu", i + 1);
    names.push_back(std::string(name) + ".png");
    names.push_back(std::string(name) + ".ply");
  }
  for (const std::string& name : names) refuseOverwritingInputs(folder / name, {source});
  StagedFolder staged(folder);
  const std::string json = alertsJson(report, top).dump(2) + "\n";
  writeFileAtomic(staged.path() / "alerts.json", std::vector<uint8_t>(json.begin(), json.end()));
  const SessionMap now = map.snapshot(report.time_s);
  if (!now.empty()) {
    const auto [d, seg] = ranked(report, n);
    writePng(staged.path() / "alerts.png", renderChangeView(now, d, seg));
  }
  for (size_t i = 0; i < n; ++i) {
    const Alert& a = report.alerts[i];
    char stem[32];
    std::snprintf(stem, sizeof stem, "alert_%02zu", i + 1);
    const DiffMap part = componentDiff(report.diff, a.component);
    exportDiffPly(staged.path() / (std::string(stem) + ".ply"), part, part.cells());
    const SessionMap around = crop(now, a.component.bbox_min_m, a.component.bbox_max_m, 1.0);
    if (around.empty()) continue;
    Segmentation one;
    Component c = a.component;
    c.id = static_cast<uint32_t>(i + 1);
    c.cells.resize(part.cells().size());
    for (size_t k = 0; k < c.cells.size(); ++k) c.cells[k] = static_cast<uint32_t>(k);
    one.components.push_back(std::move(c));
    TopViewSettings view;
    view.pixels_per_voxel = 4;
    writePng(staged.path() / (std::string(stem) + ".png"), renderChangeView(around, part, one, view));
  }
  staged.commit();
}

}  // namespace chronomap
