#pragma once
/// @file
/// From a recording to a session map: open a dataset, integrate it (with its poses corrected),
/// and register several sessions to their consensus, integrating each again with its correction.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "chronomap/align/pose_correction.h"
#include "chronomap/align/register.h"
#include "chronomap/align/up_axis.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/registry.h"
#include "chronomap/ingest/ros/rosbag.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/pipeline/progress.h"

namespace chronomap {

/// Which way is up in the recordings' world frame (docs/frames.md). The frames are turned so
/// that it becomes +z (DatasetSettings::world_rotation) before anything else reads them: the
/// maps, and every view, cost map and route computed from them, then have z up.
struct UpSettings {
  std::optional<UpAxis> axis;  ///< given (--up); none: +z, as recorded (build: the map's own when it records one)
  bool estimate = false;       ///< --up auto: estimateUpAxis on the recording (build: on the first one); axis unused
};

/// The up axis a recording or a build uses, and where it came from.
struct ChosenUp {
  UpAxis axis = UpAxis::PlusZ;
  /// "default" (+z, as recorded), "given" (--up), "auto" (estimated), "map" (the 4D map's own).
  std::string from = "default";
  std::optional<UpEstimate> estimate;  ///< when estimated
  /// The metadata a map records for it ("up", "up_from", "world_rotation": the rotation applied
  /// to the recordings' world frame, row by row); empty for +z as recorded, so that such maps keep
  /// their bytes.
  nlohmann::json metadata() const;
};

/// How a recording becomes a session map: how it is read, and how it is integrated.
struct SessionSettings {
  double resolution_m = 0.05;
  DatasetSettings dataset;
  IntegratorSettings integrator;
  UpSettings up;
};

/// The up axis `up` asks for: the given one, or (estimate) the one estimateUpAxis finds in the
/// recording at `path` as read with `dataset` (its world_rotation ignored).
/// @throw as openRecording and estimateUpAxis.
ChosenUp chooseUp(const UpSettings& up, const std::filesystem::path& path, const DatasetSettings& dataset);

/// The up axis' members of a map's metadata ("up", "up_from", "world_rotation": ChosenUp::metadata),
/// an empty object when it has none.
nlohmann::json upKeysOf(const nlohmann::json& meta);

/// The up a 4D map's metadata records: its "up" (from "map"), else +z as recorded; nothing for
/// metadata that is not an object. @throw FormatError naming `source` for an unknown axis.
ChosenUp storedUp(const nlohmann::json& meta, const std::string& source);

/// A recording integrated into a session map.
struct IntegratedSession {
  SessionMap map;
  IntegrationStats stats;
  std::optional<double> recorded_at;  ///< from the dataset's own timestamps, if any
  std::string format;                 ///< the layout that was read ("tum", "3dmatch", "clouds")
  size_t frames_dropped = 0;
  std::vector<Eigen::Vector3d> sensor_positions;  ///< of every frame, as recorded (before the correction)
  std::string dropped_reasons;  ///< why frames were dropped, when the reader says (Dataset::droppedReasons)
  std::vector<Eigen::Isometry3d> poses;  ///< T_world_sensor of every frame, as read (turned upright, before the correction)
  ChosenUp up;  ///< the up axis the frames were turned for
  /// Limits that dropped many of the points (droppedPointsWarnings); the front doors print them.
  std::vector<std::string> warnings;
};

/// Registers every reader this build has (the bag readers of ingest/ros when built with them)
/// and returns them in detection order. Every front door calls it (or openRecording) before it
/// names or opens a format; safe to call any number of times.
std::vector<DatasetReader> registerReaders();

/// parseDatasetFormat after registerReaders(): what the CLI's --format and Python's format= read.
/// @throw UsageError for a name no reader of this build has.
std::string parseRecordingFormat(const std::string& name);

/// The topics of a ROS 1 or ROS 2 bag (ingest/ros/rosbag.h's listBag).
/// @throw UsageError when chronomap was built without the bag readers; as listBag otherwise.
std::vector<BagTopic> listBagTopics(const std::filesystem::path& path, std::string* note = nullptr);

/// openDataset after registerReaders(): what the CLI, Python and the workflows open recordings with.
std::unique_ptr<Dataset> openRecording(const std::filesystem::path& path, const DatasetSettings& settings = {});

/// The recording at `path` opened as integrateDataset() opens it: its frames turned for
/// settings.up (chooseUp), the axis chosen written to `up` when given.
/// @throw as openRecording and chooseUp.
std::unique_ptr<Dataset> openForIntegration(const std::filesystem::path& path, const SessionSettings& settings,
                                            ChosenUp* up = nullptr);

/// Opens and integrates the recording at `path` (openForIntegration), every pose corrected by
/// `correction`; reports the frames as work labelled `label` (none when empty). With `sharing`,
/// other processes cast some of its frames (integrate()); the map is the same.
/// @throw DataError when no point could be integrated; whatever the reader throws for bad input.
IntegratedSession integrateDataset(const std::filesystem::path& path, const SessionSettings& settings,
                                   const PoseCorrection& correction = {}, const Progress& progress = {},
                                   const std::string& label = "integrating", FrameSharing* sharing = nullptr);

/// The metadata `chronomap integrate` writes into a session map file: what was read, how, and
/// when it was recorded.
nlohmann::json sessionMetadata(const std::filesystem::path& dataset, const IntegratedSession& session,
                               const SessionSettings& settings);

/// The depth image cache's default budget: 3 GiB, or a quarter of the machine's memory when that
/// is less.
size_t defaultDepthCacheBytes();

/// How sessions are registered to their consensus (align/register.h).
struct RegistrationSettings {
  int rounds = 3;  ///< each against the consensus the previous one left, in [1, 10]
  RegisterSettings align;
  /// Registration reads every frame up to 8 times (each re-integration, each drift round): the
  /// decoded depth images are kept between the reads up to this many bytes (DepthImageCache;
  /// about 154 KB a frame at 320 x 240, 2.5 GB for floor66's 66 sessions), so the PNG files
  /// are decoded once each. 0: none kept. The corrections do not depend on it.
  size_t depth_cache_bytes = defaultDepthCacheBytes();
};

/// The registration the README recommends for a robot's sessions and the demo runs: 3 rounds,
/// then the drift per frame with knots every 20 frames, planar (x, y and heading), fitted on the
/// frames' points. `chronomap build --register --register-drift 20 --register-planar
/// --register-points`.
RegistrationSettings recommendedRegistration();

/// The registration for sessions whose poses come from an odometry that drifts with the distance
/// travelled (no localisation against a map): 3 rounds with a 6-voxel neighbourhood, then 3 drift
/// rounds with knots every 0.5 m of the sensor's path (the second and third at 3 voxels), planar,
/// fitted on the frames' points, the motion all sessions share taken out after every round. The
/// radii were chosen on the Kinect model's training seeds 1-5 (docs/changes.md). `chronomap build
/// --register-preset odometry`.
RegistrationSettings odometryRegistration();

/// A registration by its name: "localiser" (recommendedRegistration()) or "odometry"
/// (odometryRegistration()); UsageError naming both otherwise.
RegistrationSettings registrationNamed(const std::string& name);

/// Registers the session maps integrated from `paths` (in that order, with `sensor_positions` as
/// read: turned for settings.up, whose auto is estimated on the first path) to their consensus, integrating each recording again with its correction (in
/// parallel, unreported); `maps` become the corrected sessions. `reports`, when given, receives
/// each session's last registration report. `prior`: the consensus of sessions registered
/// before, joined to every round's consensus unmoved (registerSessions). @return each
/// session's correction.
std::vector<PoseCorrection> registerDatasets(std::vector<SessionMap>& maps, std::span<const std::filesystem::path> paths,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions,
                                             const SessionSettings& settings, const RegistrationSettings& registration,
                                             std::vector<RegisterReport>* reports = nullptr,
                                             const SessionMap* prior = nullptr);

}  // namespace chronomap
