#include "chronomap/pipeline/map4d.h"

#include <algorithm>
#include <memory>
#include <optional>
#include <span>
#include <sstream>
#include <utility>

#include "chronomap/align/consensus.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/pipeline/distributed.h"
#include "build_steps.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

int64_t nodesAddedAt(const TemporalMap& map, double time_s) {
  for (const auto& s : map.sessions()) {
    if (s.time_s == time_s) return s.nodes_added;
  }
  return 0;
}

std::optional<double> givenTime(const BuildSettings& s, size_t i) {
  return s.times_s.empty() ? std::nullopt : s.times_s[i];
}

}  // namespace

namespace pipeline_detail {

void checkInputs(const BuildSettings& s) {
  if (s.realign) s.realign->validate();  // bad settings fail before integrating
  if (!s.times_s.empty() && s.times_s.size() != s.datasets.size()) {
    throw UsageError(std::to_string(s.times_s.size()) + " time(s) given for " + std::to_string(s.datasets.size()) +
                     " dataset(s)");
  }
  for (const auto& d : s.datasets) {
    if (!fs::exists(d)) throw UsageError("dataset '" + d.string() + "' does not exist");
  }
  checkOutputs({{s.map, "MAP", fs::is_directory(s.map)}}, s.datasets);  // a folder: a tiled map
}

void refuseClashes(const BuildSettings& s, const TemporalMap& map) {
  if (s.replace) return;
  for (size_t i = 0; i < s.datasets.size(); ++i) {
    const std::optional<double> t = givenTime(s, i);
    if (!t) continue;
    for (const auto& stored : map.sessions()) {
      if (stored.time_s == *t) {
        throw UsageError(s.map.string() + " already holds a session at " + formatTime(stored.time_s) + " (given for " +
                         s.datasets[i].string() + "); use --replace or another time");
      }
    }
  }
}

Pending integrateOne(const BuildSettings& s, size_t i, FrameSharing* sharing) {
  std::ostringstream step;  // (a chain of string + trips GCC 12's -Wrestrict)
  step << "[" << i + 1 << "/" << s.datasets.size() << "] " << s.datasets[i].string();
  s.progress.say(step.str());
  IntegratedSession session = integrateDataset(s.datasets[i], s.session, {}, s.progress, "integrating", sharing);
  const std::optional<double> given = givenTime(s, i);
  const std::optional<double> t = given ? given : session.recorded_at;
  if (!t) {
    throw UsageError(s.datasets[i].string() + " has no timestamps (" + session.format +
                     " datasets do not carry times); give one per dataset with --times");
  }
  return {i, *t, std::move(session)};
}

void sortByTime(const BuildSettings& s, std::vector<Pending>& pending) {
  std::stable_sort(pending.begin(), pending.end(), [](const Pending& a, const Pending& b) { return a.time_s < b.time_s; });
  for (size_t i = 1; i < pending.size(); ++i) {
    if (pending[i].time_s == pending[i - 1].time_s) {
      throw UsageError(s.datasets[pending[i - 1].index].string() + " and " + s.datasets[pending[i].index].string() +
                       " have the same time " + formatTime(pending[i].time_s));
    }
  }
}

}  // namespace pipeline_detail

using pipeline_detail::Pending;

std::vector<PoseCorrection> pipeline_detail::registerPending(const BuildSettings& s, std::vector<Pending>& pending,
                                                            const SessionMap* prior) {
  std::vector<SessionMap> maps;
  std::vector<std::vector<Eigen::Vector3d>> positions;
  std::vector<fs::path> paths;
  for (Pending& p : pending) {
    maps.push_back(std::move(p.session.map));
    positions.push_back(p.session.sensor_positions);
    paths.push_back(s.datasets[p.index]);
  }
  s.progress.say("registering " + std::to_string(maps.size()) + " session(s), " +
                 std::to_string(s.registration->rounds) + " round(s)" +
                 (prior ? ", with the stored sessions' consensus" : ""));
  std::vector<PoseCorrection> found = registerDatasets(maps, paths, positions, s.session, *s.registration, nullptr, prior);
  // Nothing reads the frames again: the decoded depth images go before the sessions are added.
  if (s.session.dataset.depth_cache) s.session.dataset.depth_cache->clear();
  for (size_t i = 0; i < pending.size(); ++i) pending[i].session.map = std::move(maps[i]);
  return found;
}

BuildSettings pipeline_detail::withRegistrationCache(const BuildSettings& given) {
  BuildSettings s = given;
  if (s.registration && s.registration->depth_cache_bytes > 0 && !s.session.dataset.depth_cache) {
    s.session.dataset.depth_cache = std::make_shared<DepthImageCache>(s.registration->depth_cache_bytes);
  }
  return s;
}

namespace {

/// Re-aligns every session against the consensus of all given; @return the voxels each moved.
std::vector<size_t> realignPending(const BuildSettings& s, std::vector<Pending>& pending) {
  std::vector<const SessionMap*> all;
  for (const Pending& p : pending) all.push_back(&p.session.map);
  const SessionMap avg = consensus(std::span<const SessionMap* const>(all));
  std::vector<size_t> moved;
  for (Pending& p : pending) {
    s.progress.say("re-aligning " + s.datasets[p.index].string());
    RealignReport r;
    p.session.map = realign(p.session.map, avg, *s.realign, &r);
    moved.push_back(r.moved());
  }
  return moved;
}

}  // namespace

TemporalMap openOrCreate(const fs::path& path, double resolution_m, const ChangeCriterion& criterion, bool& created,
                         TemporalFileLayout* layout, nlohmann::json* meta) {
  created = !fs::exists(path);
  if (meta) *meta = nlohmann::json::object();
  if (created) return TemporalMap(resolution_m, criterion);
  TemporalMap map;
  if (meta) {
    const CmapFile file = readCmap(path);
    map = temporalMapFrom(file, path.string());
    if (layout) *layout = layoutOf(file);
    *meta = userMetadataOf(file);
  } else {
    map = readTemporalMap(path, layout);
  }
  if (map.resolution_m() != resolution_m) {
    throw UsageError(path.string() + ": the 4D map has resolution " + std::to_string(map.resolution_m()) +
                     " m but the session has " + std::to_string(resolution_m) + " m");
  }
  return map;
}

ChosenUp chooseBuildUp(const BuildSettings& s, bool created, const nlohmann::json& stored) {
  if (created) return s.datasets.empty() ? ChosenUp{} : chooseUp(s.session.up, s.datasets[0], s.session.dataset);
  const ChosenUp own = storedUp(stored, s.map.string());
  if (s.session.up.axis && !s.session.up.estimate && *s.session.up.axis != own.axis) {
    throw UsageError(std::string("--up ") + toString(*s.session.up.axis) + ": " + s.map.string() +
                     " holds sessions with up " + toString(own.axis) +
                     (own.from == "map" ? "" : " (as recorded)") + "; give --up " + toString(own.axis) +
                     " (or none), or build a new map");
  }
  return own;
}

namespace pipeline_detail {

BuildSettings withUp(const BuildSettings& given, const ChosenUp& up) {
  BuildSettings s = given;
  s.session.up = {up.axis, false};
  s.session.dataset.world_rotation.reset();
  if (up.axis != UpAxis::PlusZ) s.session.dataset.world_rotation = uprightRotation(up.axis);
  if (up.from == "auto") {
    s.progress.say(std::string("up: ") + toString(up.axis) + " (estimated from " + s.datasets[0].string() + ")");
  }
  return s;
}

void refuseOtherUp(const fs::path& session, const ChosenUp& session_up, const fs::path& map, const ChosenUp& map_up) {
  if (session_up.axis == map_up.axis) return;
  throw UsageError(session.string() + " was integrated with up " + toString(session_up.axis) + " but " +
                   map.string() + " holds sessions with up " + toString(map_up.axis) +
                   "; integrate it again with --up " + toString(map_up.axis));
}

nlohmann::json mapMetadata(const nlohmann::json& stored, const ChosenUp& up) {
  return up.from == "map" ? upKeysOf(stored) : up.metadata();
}

}  // namespace pipeline_detail

BuildResult build(const BuildSettings& given) {
  pipeline_detail::checkInputs(given);
  // Registration reads every frame again: the first read already keeps the decoded depth images.
  BuildSettings s = pipeline_detail::withRegistrationCache(given);
  // Held to the end: an add to the same map meanwhile would otherwise be lost by the rewrite. A
  // map that does not exist yet locks its folder: two commands creating it run one after the other.
  const FileLock lock(s.map, FileLock::Missing::LockFolder);
  bool created = false;
  nlohmann::json stored;
  TemporalMap map = openOrCreate(s.map, s.session.resolution_m, s.criterion, created, nullptr, &stored);
  pipeline_detail::refuseClashes(s, map);
  // One up for every session, chosen before the first is read (auto: estimated on the first).
  const ChosenUp up = chooseBuildUp(s, created, stored);
  s = pipeline_detail::withUp(s, up);
  std::vector<Pending> pending;
  for (size_t i = 0; i < s.datasets.size(); ++i) pending.push_back(pipeline_detail::integrateOne(s, i));
  pipeline_detail::sortByTime(s, pending);
  return pipeline_detail::finishBuild(s, map, created, pending, up, stored);
}

std::optional<double> pipeline_detail::timeBeforeIntegrating(const BuildSettings& s, size_t i) {
  if (const std::optional<double> given = givenTime(s, i)) return given;
  try {
    return openForIntegration(s.datasets[i], s.session)->recordedAt();
  } catch (const std::exception&) {
    return std::nullopt;  // integrating it will say why
  }
}

BuiltSession pipeline_detail::addPending(const BuildSettings& s, TemporalMap& map, const Pending& p,
                                         const std::optional<PoseCorrection>& correction,
                                         std::optional<size_t> realigned) {
  const fs::path& dataset = s.datasets[p.index];
  BuiltSession b;
  b.dataset = dataset;
  b.time_s = p.time_s;
  b.report = map.add(p.time_s, p.session.map, AddSettings{s.replace, dataset.filename().string()});
  b.nodes_added = nodesAddedAt(map, p.time_s);
  b.nodes_separate = p.session.map.innerCount() + p.session.map.leafCount();
  b.points = p.session.stats.points;
  b.correction = correction;
  b.recorded_poses = p.session.poses;
  b.warnings = p.session.warnings;
  b.poses.reserve(b.recorded_poses.size());
  for (size_t f = 0; f < b.recorded_poses.size(); ++f) {
    b.poses.push_back(b.correction ? b.correction->apply(b.recorded_poses[f], f) : b.recorded_poses[f]);
  }
  b.realigned_voxels = realigned;
  return b;
}

BuildResult pipeline_detail::finishBuild(const BuildSettings& s, TemporalMap& map, bool created,
                                         std::vector<Pending>& pending, const ChosenUp& up,
                                         const nlohmann::json& stored, std::vector<BuiltSession> added_before) {
  BuildResult result;
  result.created = created;
  result.up = up;
  result.added = std::move(added_before);
  std::vector<PoseCorrection> corrections;
  if (s.registration) {
    // Sessions added to a map that holds some are registered against those too: the 4D map's
    // consensus over its sessions joins every round's consensus, unmoved (not when replacing,
    // where it would hold the sessions being replaced).
    std::optional<SessionMap> prior;
    if (map.sessionCount() > 0 && !s.replace) {
      prior = consensus(map, map.sessions().front().time_s, map.sessions().back().time_s);
    }
    corrections = registerPending(s, pending, prior ? &*prior : nullptr);
  }
  std::vector<size_t> moved;
  if (s.realign) moved = realignPending(s, pending);
  for (size_t i = 0; i < pending.size(); ++i) {
    result.added.push_back(addPending(s, map, pending[i],
                                      corrections.empty() ? std::nullopt : std::optional<PoseCorrection>(corrections[i]),
                                      moved.empty() ? std::nullopt : std::optional<size_t>(moved[i])));
  }
  // One atomic write at the end: a crash leaves the previous map (or none) on disk.
  writeTemporalMap(s.map, map, mapMetadata(stored, up));
  result.sessions = map.sessionCount();
  result.nodes = map.counts().nodes();
  result.file_bytes = fs::file_size(s.map);
  return result;
}

const char* toString(WritePolicy policy) {
  switch (policy) {
    case WritePolicy::Auto: return "auto";
    case WritePolicy::Append: return "append";
    case WritePolicy::Rewrite: return "rewrite";
  }
  return "?";
}

WritePolicy parseWritePolicy(const std::string& name) {
  for (WritePolicy p : {WritePolicy::Auto, WritePolicy::Append, WritePolicy::Rewrite}) {
    if (name == toString(p)) return p;
  }
  throw UsageError("write policy must be auto, append or rewrite, not '" + name + "'");
}

double pipeline_detail::sessionTime(const AddSessionSettings& s, const CmapFile& file) {
  if (s.time_s) return *s.time_s;
  const nlohmann::json meta = metadataOf(file);
  if (!meta.contains("recorded_at") || !meta["recorded_at"].is_number()) {
    throw UsageError(s.session.string() + " does not say when it was recorded; give --time");
  }
  return meta["recorded_at"].get<double>();
}

AddSessionResult addSession(const AddSessionSettings& s) {
  if (s.realign) s.realign->validate();
  checkOutputs({{s.map, "MAP", fs::is_directory(s.map)}}, {s.session});
  const CmapFile file = readCmap(s.session);
  SessionMap session = sessionMapFrom(file, s.session.string());
  AddSessionResult r;
  r.time_s = pipeline_detail::sessionTime(s, file);
  // One add at a time per map: a second one waits here, then reads what the first wrote (also
  // when the first created the map).
  const FileLock lock(s.map, FileLock::Missing::LockFolder);
  TemporalFileLayout layout;
  nlohmann::json stored;
  TemporalMap map = openOrCreate(s.map, session.resolution_m(), s.criterion, r.created, &layout, &stored);
  // One up for every session of a map: a new map takes the session's (and records it).
  const nlohmann::json session_meta = metadataOf(file);
  const ChosenUp session_up = storedUp(session_meta, s.session.string());
  const ChosenUp map_up = r.created ? session_up : storedUp(stored, s.map.string());
  pipeline_detail::refuseOtherUp(s.session, session_up, s.map, map_up);
  r.up = map_up.axis;
  // What a rewrite keeps of the map's metadata: its up (a new map: the session's).
  const nlohmann::json meta = upKeysOf(r.created ? session_meta : stored);
  if (s.realign) {
    // The consensus of every session stored so far (each time's snapshot) and this one.
    SessionMap avg = map.sessionCount() ? consensus(map, map.sessions().front().time_s, map.sessions().back().time_s)
                                        : SessionMap(session.resolution_m());
    avg.merge(session);
    RealignReport realigned;
    session = realign(session, avg, *s.realign, &realigned);
    r.realigned_voxels = realigned.moved();
    // As the record below keeps it (lengths, colour sums and positions quantised), so that a
    // reader replaying the record builds the map this add holds.
    session = asStored(session);
  }
  const AddSettings add_settings{s.replace, s.session.filename().string()};
  r.report = map.add(r.time_s, session, add_settings);
  // Append the session as a record (the file's bytes so far stay as they are), or write the whole
  // map again, folding earlier records in: "auto" appends while the records stay smaller than the
  // base, so that reading never replays more than the base holds.
  const std::vector<uint8_t> record =
      r.created ? std::vector<uint8_t>{} : encodeSessionRecord(r.time_s, session, add_settings);
  r.appended = !r.created && (s.write == WritePolicy::Append ||
                              (s.write == WritePolicy::Auto &&
                               layout.appended_bytes + record.size() <= layout.base_bytes));
  if (r.appended) {
    appendToFile(s.map, layout.completeBytes(), record);
    r.record_bytes = record.size();
  } else {
    writeTemporalMap(s.map, map, meta);
  }
  r.nodes_added = nodesAddedAt(map, r.time_s);
  r.sessions = map.sessionCount();
  r.nodes = map.counts().nodes();
  r.file_bytes = fs::file_size(s.map);
  return r;
}

}  // namespace chronomap
