#pragma once
/// @file
/// Workflows on a 4D map file: build one from recordings (integrated, ordered by time,
/// registered, re-aligned, added and written once), and add one session map to it with the
/// append-or-rewrite policy. Both hold the map's file lock while they read and write it.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "chronomap/align/pose_correction.h"
#include "chronomap/align/realign.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/progress.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// What build() does.
struct BuildSettings {
  std::filesystem::path map;                   ///< the 4D map (.cmap), created when missing
  std::vector<std::filesystem::path> datasets;  ///< one recording per session
  /// One time per dataset, or empty: then each dataset's own first timestamp (TUM).
  std::vector<std::optional<double>> times_s;
  bool replace = false;  ///< replace sessions stored at the same times instead of refusing
  ChangeCriterion criterion;  ///< for a new map
  SessionSettings session;
  /// Register the sessions to the consensus of all given, integrating each again with its correction.
  /// build() then gives the datasets a depth image cache from the first integration on (unless
  /// session.dataset has one) and empties it after the registration.
  std::optional<RegistrationSettings> registration;
  /// Re-align each session against the consensus of all given (thesis §2.2).
  std::optional<RealignSettings> realign;
  Progress progress;
};

/// One session build() added.
struct BuiltSession {
  std::filesystem::path dataset;
  double time_s = 0.0;
  AddReport report;
  int64_t nodes_added = 0;     ///< nodes the session added to the 4D map
  uint64_t nodes_separate = 0; ///< nodes of the session map on its own
  uint64_t points = 0;         ///< points integrated
  std::optional<PoseCorrection> correction;   ///< with registration
  /// T_world_sensor of every frame as the recording gives it (turned for the map's up axis,
  /// docs/frames.md), and as integrated (with the correction applied; the same poses without
  /// registration).
  std::vector<Eigen::Isometry3d> recorded_poses, poses;
  std::optional<size_t> realigned_voxels;     ///< with re-alignment
  std::vector<std::string> warnings;          ///< IntegratedSession::warnings
};

/// What build() did.
struct BuildResult {
  bool created = false;
  size_t sessions = 0;  ///< in the map now
  size_t nodes = 0;     ///< of the map now
  uint64_t file_bytes = 0;
  std::vector<BuiltSession> added;  ///< in time order
  ChosenUp up;  ///< the up axis of the map's sessions
};

/// Integrates every dataset, sorts the sessions by time, registers and re-aligns them when
/// asked, adds them to the map (created when missing) and writes it once, atomically: a failure
/// leaves the previous file (or none).
/// @throw UsageError for a missing dataset, clashing or missing times, a map of another
/// resolution; whatever integration and the readers throw.
BuildResult build(const BuildSettings& settings);

/// How addSession() writes the map.
enum class WritePolicy : uint8_t {
  Auto,     ///< append while the appended sessions take fewer bytes than the rest of the file
  Append,   ///< add the session at the end of the file, the bytes before it untouched
  Rewrite,  ///< write the whole map again, folding appended sessions in
};
/// "auto", "append", "rewrite".
const char* toString(WritePolicy policy);
/// Inverse of toString. @throw UsageError for another name.
WritePolicy parseWritePolicy(const std::string& name);

/// What addSession() does.
struct AddSessionSettings {
  std::filesystem::path map;      ///< the 4D map (.cmap), created when missing
  std::filesystem::path session;  ///< a session map file
  /// When the session was recorded; default: the time its file records.
  std::optional<double> time_s;
  bool replace = false;
  WritePolicy write = WritePolicy::Auto;
  ChangeCriterion criterion;  ///< for a new map
  /// Re-align the session against the consensus of the stored sessions and itself first.
  std::optional<RealignSettings> realign;
  /// A tiled map folder (streamAddSession): groups of tiles written at once, each on its own
  /// thread (StreamSettings::threads); 0: one per core. The files do not depend on it.
  int threads = 0;
};

/// What addSession() did.
struct AddSessionResult {
  bool created = false;
  bool appended = false;       ///< appended as a record, else the map was written whole
  double time_s = 0.0;
  AddReport report;
  int64_t nodes_added = 0;
  uint64_t record_bytes = 0;   ///< bytes appended
  std::optional<size_t> realigned_voxels;
  UpAxis up = UpAxis::PlusZ;  ///< the map's up axis (the session's must be the same)
  size_t sessions = 0;
  size_t nodes = 0;
  uint64_t file_bytes = 0;
};

/// Adds a session map file to a 4D map file. A second add to the same map waits for the first
/// and then reads what it wrote.
/// @throw UsageError when the time is neither given nor recorded, or resolutions differ.
AddSessionResult addSession(const AddSessionSettings& settings);

/// The 4D map at `path`, or a new one when the file does not exist (`created` says which);
/// `meta`, when given, receives the stored metadata block (an empty object for a new map).
/// @throw UsageError when the stored map has another resolution.
TemporalMap openOrCreate(const std::filesystem::path& path, double resolution_m, const ChangeCriterion& criterion,
                         bool& created, TemporalFileLayout* layout = nullptr, nlohmann::json* meta = nullptr);

/// The up axis a build into a map uses (docs/frames.md): a map that exists keeps its own (what
/// its metadata `stored` records, else +z as recorded), which --up auto reuses and a different
/// --up is refused for; a new map takes the given axis, or auto's estimate on the first dataset.
/// @throw UsageError naming --up for an axis other than the map's; as chooseUp.
ChosenUp chooseBuildUp(const BuildSettings& settings, bool created, const nlohmann::json& stored);

}  // namespace chronomap
