#include "chronomap/pipeline/session.h"

#include <unistd.h>

#include <algorithm>
#include <memory>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/ingest/registry.h"
#if CHRONOMAP_HAVE_ROS
#include "chronomap/ingest/ros/readers.h"
#endif

namespace chronomap {

std::vector<DatasetReader> registerReaders() {
#if CHRONOMAP_HAVE_ROS
  registerRosReaders();
#endif
  return datasetReaders();
}

std::string parseRecordingFormat(const std::string& name) {
  registerReaders();
  return parseDatasetFormat(name);
}

std::vector<BagTopic> listBagTopics(const std::filesystem::path& path, std::string* note) {
#if CHRONOMAP_HAVE_ROS
  return listBag(path, note);
#else
  (void)note;
  throw UsageError(path.string() + ": this chronomap was built without the ROS bag readers (CHRONOMAP_ROS=OFF)");
#endif
}

std::unique_ptr<Dataset> openRecording(const std::filesystem::path& path, const DatasetSettings& settings) {
  registerReaders();
  return openDataset(path, settings);
}

size_t defaultDepthCacheBytes() {
  const size_t cap = size_t{3} << 30;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return cap;
  return std::min(cap, static_cast<size_t>(pages) / 4 * static_cast<size_t>(page));
}

nlohmann::json ChosenUp::metadata() const {
  if (from == "default" && axis == UpAxis::PlusZ) return nlohmann::json::object();
  const Eigen::Matrix3d r = uprightRotation(axis);
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < 3; ++i) rows.push_back({r(i, 0), r(i, 1), r(i, 2)});
  return {{"up", toString(axis)}, {"up_from", from}, {"world_rotation", rows}};
}

ChosenUp chooseUp(const UpSettings& up, const std::filesystem::path& path, const DatasetSettings& dataset) {
  ChosenUp out;
  if (up.estimate) {
    DatasetSettings as_recorded = dataset;
    as_recorded.world_rotation.reset();
    as_recorded.colour = false;
    UpEstimateSettings estimate;
    // A bag's clouds may come from a lidar (up +z in its frame), not a camera: no upright cue.
    if (!dataset.bag.cloud_topic.empty()) estimate.sensor_up.setZero();
    out.estimate = estimateUpAxis(*openRecording(path, as_recorded), estimate);
    out.axis = out.estimate->axis;
    out.from = "auto";
  } else if (up.axis) {
    out.axis = *up.axis;
    out.from = "given";
  }
  return out;
}

nlohmann::json upKeysOf(const nlohmann::json& meta) {
  nlohmann::json out = nlohmann::json::object();
  for (const char* key : {"up", "up_from", "world_rotation"}) {
    if (meta.is_object() && meta.contains(key)) out[key] = meta[key];
  }
  return out;
}

ChosenUp storedUp(const nlohmann::json& meta, const std::string& source) {
  ChosenUp out;
  if (!meta.is_object() || !meta.contains("up")) return out;
  try {
    out.axis = parseUpAxis(meta.at("up").get<std::string>());
  } catch (const std::exception& e) {
    throw FormatError(source + ": the metadata's up axis is unreadable (" + e.what() + ")");
  }
  out.from = "map";
  return out;
}

std::unique_ptr<Dataset> openForIntegration(const std::filesystem::path& path, const SessionSettings& settings,
                                            ChosenUp* up) {
  const ChosenUp chosen = chooseUp(settings.up, path, settings.dataset);
  if (up) *up = chosen;
  if (chosen.axis == UpAxis::PlusZ) return openRecording(path, settings.dataset);
  DatasetSettings dataset = settings.dataset;
  dataset.world_rotation = uprightRotation(chosen.axis);
  return openRecording(path, dataset);
}

IntegratedSession integrateDataset(const std::filesystem::path& path, const SessionSettings& settings,
                                   const PoseCorrection& correction, const Progress& progress,
                                   const std::string& label, FrameSharing* sharing) {
  // Other processes cast the frames as the recording reads them (serveSharedFrames in distributed.cpp).
  if (sharing && !correction.isIdentity()) throw Error("frames of a corrected recording are not shared");
  ChosenUp up;
  auto dataset = openForIntegration(path, settings, &up);
  IntegratedSession out{SessionMap(settings.resolution_m), {}, dataset->recordedAt(), dataset->format(),
                        dataset->framesDropped(), {}, dataset->droppedReasons(), {}, up, {}};
  out.sensor_positions.reserve(dataset->size());
  out.poses.reserve(dataset->size());
  for (size_t i = 0; i < dataset->size(); ++i) {
    out.poses.push_back(dataset->poseOf(i));
    out.sensor_positions.push_back(out.poses.back().translation());
  }
  // Without a correction the dataset is read directly (frames already in memory are not copied).
  const CorrectedFrames frames(*dataset, correction);
  const FrameSource& source = correction.isIdentity() ? static_cast<const FrameSource&>(*dataset) : frames;
  out.stats = integrate(
      source, out.map, settings.integrator, [&](size_t done, size_t total) { progress.advance(label, done, total); },
      sharing);
  if (out.stats.points == 0) {
    throw DataError(path.string() + ": no valid points within " + std::to_string(settings.integrator.max_range_m) +
                    " m in " + std::to_string(out.stats.frames) + " frame(s) (" +
                    std::to_string(out.stats.pointsSkipped()) + " skipped); nothing to write");
  }
  out.warnings = droppedPointsWarnings(out.stats, settings.integrator);
  return out;
}

nlohmann::json sessionMetadata(const std::filesystem::path& dataset, const IntegratedSession& session,
                               const SessionSettings& settings) {
  nlohmann::json meta = {{"created_by", "chronomap integrate"},
                         {"dataset", std::filesystem::absolute(dataset).lexically_normal().string()},
                         {"format", session.format},
                         {"frames", session.stats.frames},
                         {"points", session.stats.points},
                         {"max_range_m", settings.integrator.max_range_m},
                         {"fast", settings.integrator.fast},
                         {"compressed", settings.integrator.compress_free},
                         {"hit_positions", settings.integrator.hit_positions}};
  const int carve_level = carveLevelFor(settings.integrator, session.map.resolution_m());
  if (carve_level > 0) meta["carve_level"] = carve_level;
  if (session.recorded_at) meta["recorded_at"] = *session.recorded_at;
  meta.update(session.up.metadata());
  return meta;
}

RegistrationSettings recommendedRegistration() {
  RegistrationSettings r;
  r.rounds = 3;
  r.align.drift_knot_frames = 20;
  r.align.planar = true;
  r.align.drift_points = true;
  return r;
}

RegistrationSettings odometryRegistration() {
  RegistrationSettings r;
  r.rounds = 3;
  r.align.radius_voxels = 6.0;
  r.align.drift_knot_frames = 0;
  r.align.drift_knot_m = 0.5;
  r.align.drift_rounds = 3;
  r.align.fine_radius_voxels = 3.0;
  r.align.planar = true;
  r.align.drift_points = true;
  r.align.keep_mean = true;
  return r;
}

RegistrationSettings registrationNamed(const std::string& name) {
  if (name == "localiser") return recommendedRegistration();
  if (name == "odometry") return odometryRegistration();
  throw UsageError("unknown registration preset '" + name + "' (localiser or odometry)");
}

std::vector<PoseCorrection> registerDatasets(std::vector<SessionMap>& maps, std::span<const std::filesystem::path> paths,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions,
                                             const SessionSettings& settings, const RegistrationSettings& registration,
                                             std::vector<RegisterReport>* reports, const SessionMap* prior) {
  // The drift fit needs the frames' points only, and the maps before each session's last
  // re-integration their occupancy only: there the colour images are left unread.
  // Every frame is read up to 8 times: its depth image is decoded once while the cache has room.
  SessionSettings full = settings;
  // One up for every session and every pass, the drift fit's reads included: estimated once, on the first.
  if (!paths.empty()) {
    full.up = {chooseUp(settings.up, paths[0], settings.dataset).axis, false};
    if (*full.up.axis != UpAxis::PlusZ) full.dataset.world_rotation = uprightRotation(*full.up.axis);
  }
  if (registration.depth_cache_bytes > 0 && !full.dataset.depth_cache) {
    full.dataset.depth_cache = std::make_shared<DepthImageCache>(registration.depth_cache_bytes);
  }
  SessionSettings geometry = full;
  geometry.dataset.colour = false;
  return registerSessions(
      maps,
      [&](size_t k, const PoseCorrection& c, bool last) {
        return integrateDataset(paths[k], last ? full : geometry, c, {}, "").map;
      },
      registration.rounds, registration.align, reports, sensor_positions,
      [&](size_t k) -> std::unique_ptr<FrameSource> { return openRecording(paths[k], geometry.dataset); }, prior);
}

}  // namespace chronomap
