// The viewer's HTTP API, as a function of a request.

#include "chronomap/view/api.h"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include "assets.h"
#include "printable.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"
#include "chronomap/view/packet.h"

namespace chronomap {

namespace {

// Error messages quote what the request sent, which need not be UTF-8: such bytes become U+FFFD
// rather than an exception (found by fuzz/fuzz_view_api.cpp).
Reply json(const nlohmann::json& j, int status = 200) {
  return {status, "application/json", j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)};
}
Reply binary(std::string body) { return {200, "application/octet-stream", std::move(body)}; }

// Refuses parameters of `path` other than `allowed` (listed in the message in that order), and
// repeated ones.
void onlyParameters(const std::string& path, const Query& query, std::initializer_list<const char*> allowed) {
  for (const auto& [name, value] : query) {
    if (std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
      std::string m = "unknown parameter '" + printable(name) + "': " + path;
      if (allowed.size() == 0) throw UsageError(m + " takes no parameters");
      m += " takes ";
      for (const char* a : allowed) m.append(a).append(a == *(allowed.end() - 1) ? "" : ", ");
      throw UsageError(m);
    }
    if (query.count(name) > 1) throw UsageError("parameter '" + printable(name) + "' given more than once: give it once");
  }
}

const std::string* find(const Query& query, const std::string& name) {
  const auto it = query.find(name);
  return it == query.end() ? nullptr : &it->second;
}

// `name=text` as received (bytes that do not print escaped), to begin an error message.
std::string received(const std::string& name, const std::string& text) { return name + "=" + printable(text); }

// A whole number in [lo, hi]; else "NAME=TEXT is not WHAT: expected a whole number from LO to HI
// (NOTE)".
uint64_t parseCount(const std::string& text, const std::string& name, uint64_t lo, uint64_t hi, const std::string& what,
                    const std::string& note = "") {
  uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v < lo || v > hi) {
    std::ostringstream m;
    m << received(name, text) << " is not " << what << ": expected a whole number from " << lo << " to " << hi;
    if (!note.empty()) m << " (" << note << ")";
    throw UsageError(m.str());
  }
  return v;
}

// `count` voxel keys separated by commas, in the order `form` names them (e.g. "x,y,z").
std::vector<uint16_t> parseKeys(const std::string& text, const std::string& name, size_t count, const std::string& form) {
  const std::string expected = "expected " + form + ", whole numbers from 0 to " + std::to_string(kKeysPerAxis - 1) +
                               " separated by commas";
  std::vector<std::string> parts(1);
  for (const char c : text) {
    if (c == ',') {
      parts.emplace_back();
    } else {
      parts.back().push_back(c);
    }
  }
  if (parts.size() != count) {
    throw UsageError(received(name, text) + " is not " + std::to_string(count) + " voxel keys: " + expected);
  }
  std::vector<uint16_t> out;
  for (const auto& part : parts) {
    uint32_t v = 0;
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), v);
    if (ec != std::errc() || end != part.data() + part.size() || v >= static_cast<uint32_t>(kKeysPerAxis)) {
      throw UsageError(received(name, text) + ": '" + printable(part) + "' is not a voxel key: " + expected);
    }
    out.push_back(static_cast<uint16_t>(v));
  }
  return out;
}

}  // namespace

Api::Api(const TemporalMap& map, std::string name, ApiSettings settings)
    : map_(map), name_(std::move(name)), settings_(settings) {
  // The change summary behind 4D diffs is built on first use; build it now, before requests
  // arrive from several threads.
  map_.forEachListChangedIn(0, 1, [](const VoxelKey&, int, std::span<const TemporalMap::Entry>) {});
}

namespace {

// The time a request names with `session` (a rank) or `time` (seconds or ISO-8601), which must
// lie within the map's sessions, or up to `beyond_last_s` past the last one (predictions).
double requestedTime(const TemporalMap& map, const Query& query, const std::string& session, const std::string& time,
                     double beyond_last_s = 0.0) {
  if (map.sessionCount() == 0) throw UsageError("the map holds no session");
  const auto* rank = find(query, session);
  const auto* t = find(query, time);
  const size_t n = map.sessionCount();
  const double last_s = map.sessions().back().time_s + beyond_last_s;
  const std::string first = formatTime(map.sessions().front().time_s), last = formatTime(last_s);
  const std::string times = "seconds since the epoch or ISO-8601 (e.g. 2012-03-01T10:00:00Z) from " + first + " to " + last +
                            (beyond_last_s > 0 ? " (a week past the last session)" : "");
  if (rank && t) throw UsageError("give " + session + "= or " + time + "=, not both");
  if (!rank && !t) {
    throw UsageError("give one of " + session + "=RANK (a session number from 0 to " + std::to_string(n - 1) + ") or " + time +
                     "=TIME (" + times + ")");
  }
  if (rank) {
    const std::string note = "the map has " + std::to_string(n) + " session" + (n == 1 ? "" : "s");
    return map.sessions()[parseCount(*rank, session, 0, n - 1, "a session number", note)].time_s;
  }
  double s = 0.0;
  try {
    s = parseTime(*t);
  } catch (const UsageError&) {
    throw UsageError(received(time, *t) + " is not a time: expected " + times);
  }
  if (beyond_last_s > 0 && s > last_s) {
    throw UsageError(received(time, *t) + " lies more than a week past the map's last session (" +
                     formatTime(map.sessions().back().time_s) + "): the temporal models predict up to " + last +
                     "; expected a time from " + first + " to " + last);
  }
  if (s < map.sessions().front().time_s - TemporalMap::kTimeSlack_s || s > last_s + TemporalMap::kTimeSlack_s) {
    throw UsageError(received(time, *t) + " lies outside the map's sessions: expected a time from " + first + " to " + last);
  }
  return s;
}

// The temporal model `model=` names.
RhythmModel requestedModel(const std::string& text) {
  std::string names;
  for (size_t i = 0; i < kRhythmModels.size(); ++i) {
    names.append(i == 0 ? "" : i + 1 == kRhythmModels.size() ? " or " : ", ").append(toString(kRhythmModels[i]));
  }
  for (RhythmModel m : kRhythmModels) {
    if (text == toString(m)) return m;
  }
  throw UsageError(received("model", text) + " is not a temporal model: expected " + names);
}

// What a prediction or cost-map request names: its time (as requestedTime, any time from the
// first session to a week past the last) and the temporal model (`model`, the combined one by
// default).
std::pair<double, RhythmModel> predictionRequest(const TemporalMap& map, const std::string& path, const Query& query) {
  onlyParameters(path, query, {"session", "t", "model"});
  const double time_s = requestedTime(map, query, "session", "t", kPredictionHorizon_s);
  RhythmModel model = RhythmModel::Combined;
  if (const auto* m = find(query, "model")) model = requestedModel(*m);
  return {time_s, model};
}

}  // namespace

Reply Api::get(const std::string& path, const Query& query) const {
  try {
    if (path == "/" || path == "/index.html") {
      onlyParameters(path, query, {});
      return {200, "text/html; charset=utf-8", servedPage()};
    }
    if (path == "/viewer.js") return {200, "application/javascript", std::string(viewerScript())};
    if (path == "/api/map") {
      onlyParameters(path, query, {});
      nlohmann::json info = mapInfoJson(map_, name_);
      info["default_max_voxels"] = settings_.default_max_voxels;
      info["max_voxels_limit"] = settings_.max_voxels_limit;
      return json(info);
    }
    if (path == "/api/snapshot") return snapshot(query);
    if (path == "/api/diff") return diffReply(query);
    if (path == "/api/history") return history(query);
    if (path == "/api/predict") return predict(query);
    if (path == "/api/costmap") return costmapReply(query);
  } catch (const UsageError& e) {
    return json({{"error", e.what()}}, 400);
  }
  return json({{"error", "no such path: " + printable(path)}}, 404);
}

Reply Api::snapshot(const Query& query) const {
  onlyParameters("/api/snapshot", query, {"session", "t", "budget", "level", "region"});
  SnapshotRequest r;
  r.time_s = requestedTime(map_, query, "session", "t");
  r.max_voxels = settings_.default_max_voxels;
  if (const auto* b = find(query, "budget")) r.max_voxels = parseCount(*b, "budget", 1, settings_.max_voxels_limit, "a cell budget");
  if (const auto* l = find(query, "level")) {
    r.min_level = static_cast<int>(parseCount(*l, "level", 0, kMaxLevel, "a level of detail"));
  }
  if (const auto* region = find(query, "region")) {
    const auto k = parseKeys(*region, "region", 6, "x0,y0,z0,x1,y1,z1");
    r.region = std::array<VoxelKey, 2>{VoxelKey{k[0], k[1], k[2]}, VoxelKey{k[3], k[4], k[5]}};
    if (k[0] > k[3] || k[1] > k[4] || k[2] > k[5]) {
      throw UsageError(received("region", *region) + ": the lower corner lies above the upper (expected x0 <= x1, y0 <= y1, z0 <= z1)");
    }
  }
  return binary(encodeSnapshot(snapshotVoxels(map_, r), map_));
}

Reply Api::diffReply(const Query& query) const {
  onlyParameters("/api/diff", query, {"from", "to", "t0", "t1", "min_voxels", "format"});
  DiffRequest r{0.0, 0.0, settings_.diff, settings_.segment};
  r.t0_s = requestedTime(map_, query, "from", "t0");
  r.t1_s = requestedTime(map_, query, "to", "t1");
  if (const auto* m = find(query, "min_voxels")) r.segment.min_voxels = parseCount(*m, "min_voxels", 1, 1u << 30, "an object size in voxels");
  const std::string* format = find(query, "format");
  if (format && *format != "binary" && *format != "json") {
    throw UsageError(received("format", *format) + " is not a reply format: expected json (the objects) or binary "
                                                   "(the default: cells for drawing)");
  }
  if (format && *format == "json") {
    // The objects as every front door lists them: the one call, with the viewer's settings.
    ChangeSettings s = recommendedChangeSettings();
    s.diff = r.diff;
    s.segment = r.segment;
    const Changes changes = findChanges(map_, r.t0_s, r.t1_s, s);
    return json({{"t0", r.t0_s},
                 {"t1", r.t1_s},
                 {"from", formatTime(r.t0_s)},
                 {"to", formatTime(r.t1_s)},
                 {"appeared_voxels", changes.appeared_voxels},
                 {"vanished_voxels", changes.vanished_voxels},
                 {"settings", changeSettingsJson(s)},
                 {"objects", changedObjectsJson(changes.objects)}});
  }
  return binary(encodeDiff(diffObjects(map_, r), r, settings_.max_diff_cells));
}

Reply Api::history(const Query& query) const {
  onlyParameters("/api/history", query, {"key", "level"});
  const auto* key = find(query, "key");
  if (!key) throw UsageError("give key=x,y,z (the voxel's keys, whole numbers from 0 to " + std::to_string(kKeysPerAxis - 1) + ")");
  const auto k = parseKeys(*key, "key", 3, "x,y,z");
  int level = 0;
  if (const auto* l = find(query, "level")) {
    level = static_cast<int>(parseCount(*l, "level", 0, kMaxHistoryLevel, "a history level"));
  }
  return json(historyJson(map_, VoxelKey{k[0], k[1], k[2]}, level));
}

const RhythmModels& Api::rhythm() const {
  if (settings_.rhythm) {
    if (!sameResolution(settings_.rhythm->resolution_m, map_.resolution_m())) {
      throw UsageError("the temporal models are for " + exactNumber(settings_.rhythm->resolution_m) +
                       " m voxels, the map has " + exactNumber(map_.resolution_m()) + " m");
    }
    return *settings_.rhythm;
  }
  std::call_once(fitted_->once, [this] {
    const auto start = std::chrono::steady_clock::now();
    const double inf = std::numeric_limits<double>::infinity();
    fitted_->models = std::make_shared<const RhythmModels>(fitRhythm(map_, -inf, inf));
    fitted_->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  });
  return *fitted_->models;
}

Reply Api::predict(const Query& query) const {
  const auto [time_s, model] = predictionRequest(map_, "/api/predict", query);
  const RhythmModels& models = rhythm();
  return binary(encodePrediction(models, model, time_s, settings_.rhythm ? 0.0 : fitted_->seconds));
}

Reply Api::costmapReply(const Query& query) const {
  const auto [time_s, model] = predictionRequest(map_, "/api/costmap", query);
  const RhythmModels& models = rhythm();
  const CostmapSettings settings;
  return binary(encodeCostmap(costmap(predictMap(map_, models, model, time_s), settings, &models), settings, model, time_s));
}

std::string encodeCostmap(const Costmap& c, const CostmapSettings& settings, RhythmModel model, double time_s) {
  std::vector<uint8_t> cost(c.cost.size());
  for (size_t i = 0; i < cost.size(); ++i) cost[i] = static_cast<uint8_t>(c.cost[i]);
  PacketWriter w;
  w.add("cost", std::span<const uint8_t>(cost));
  return w.finish({{"time_s", time_s},
                   {"model", toString(model)},
                   {"width", c.width},
                   {"height", c.height},
                   {"resolution_m", c.resolution_m},
                   {"origin_m", {c.origin_m.x(), c.origin_m.y()}},
                   {"z_min_m", settings.z_min_m},
                   {"z_max_m", settings.z_max_m}});
}

std::string encodePrediction(const RhythmModels& models, RhythmModel model, double time_s, double fit_s) {
  std::vector<uint16_t> keys;
  std::vector<uint8_t> levels;
  std::vector<float> p;
  keys.reserve(3 * models.voxels.size());
  for (const auto& v : models.voxels) {
    keys.insert(keys.end(), {v.corner.x, v.corner.y, v.corner.z});
    levels.push_back(v.level);
    p.push_back(static_cast<float>(RhythmModels::predict(v, model, time_s)));
  }
  PacketWriter w;
  w.add("keys", std::span<const uint16_t>(keys));
  w.add("levels", std::span<const uint8_t>(levels));
  w.add("p", std::span<const float>(p));
  return w.finish({{"time_s", time_s}, {"model", toString(model)}, {"cubes", levels.size()}, {"fit_s", fit_s}});
}

std::string encodeSnapshot(const VoxelSet& v, const TemporalMap& map) {
  std::vector<uint16_t> keys;
  keys.reserve(v.keys.size() * 3);
  for (const auto& k : v.keys) keys.insert(keys.end(), {k.x, k.y, k.z});
  std::vector<uint8_t> colours;
  colours.reserve(v.colours.size() * 3);
  for (const auto& c : v.colours) colours.insert(colours.end(), {c.r, c.g, c.b});
  PacketWriter w;
  w.add("keys", std::span<const uint16_t>(keys));
  w.add("levels", std::span<const uint8_t>(v.levels));
  w.add("colors", std::span<const uint8_t>(colours));
  w.add("changes", std::span<const uint8_t>(v.changes));
  w.add("since", std::span<const uint16_t>(v.since));
  w.add("members", std::span<const uint32_t>(v.members));
  nlohmann::json header{{"level", v.level},
                        {"cells", v.keys.size()},
                        {"occupied_voxels", v.occupied_voxels},
                        {"rank", v.rank ? nlohmann::json(*v.rank) : nlohmann::json()}};
  if (v.rank) header["time_s"] = map.sessions()[*v.rank].time_s;
  return w.finish(std::move(header));
}

std::string encodeDiff(const DiffObjects& o, const DiffRequest& request, size_t max_cells) {
  const auto cells = o.diff.cells();
  const size_t sent = std::min(cells.size(), max_cells);
  std::vector<uint16_t> keys;
  std::vector<uint8_t> levels, kinds;
  std::vector<uint32_t> component(o.component_of_cell.begin(), o.component_of_cell.begin() + static_cast<std::ptrdiff_t>(sent));
  keys.reserve(sent * 3);
  for (size_t i = 0; i < sent; ++i) {
    keys.insert(keys.end(), {cells[i].key.x, cells[i].key.y, cells[i].key.z});
    levels.push_back(cells[i].level);
    kinds.push_back(static_cast<uint8_t>(cells[i].kind));
  }
  PacketWriter w;
  w.add("keys", std::span<const uint16_t>(keys));
  w.add("levels", std::span<const uint8_t>(levels));
  w.add("kinds", std::span<const uint8_t>(kinds));
  w.add("component", std::span<const uint32_t>(component));
  nlohmann::json components = nlohmann::json::array();
  for (const auto& c : o.segmentation.components) components.push_back(componentJson(c));
  return w.finish({{"t0_s", request.t0_s},
                   {"t1_s", request.t1_s},
                   {"cells", cells.size()},
                   {"cells_sent", sent},
                   {"voxels", o.diff.voxelCount()},
                   {"components", std::move(components)},
                   {"dropped", o.segmentation.dropped}});
}

std::string servedPage() { return viewer_assets::page(viewer_assets::scriptTag("viewer.js"), ""); }

std::string_view viewerScript() { return viewer_assets::viewerScript(); }

std::string selfContainedPage(const std::string& data) {
  return viewer_assets::page(viewer_assets::inlineScript(viewer_assets::viewerScript()), viewer_assets::inlineData(data));
}

}  // namespace chronomap
