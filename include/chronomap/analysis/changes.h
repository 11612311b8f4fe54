#pragma once
/// @file
/// What changed between two visits, and which objects: the one call every front door asks
/// (docs/changes.md). A diff of the two states, its changes segmented into objects, and each
/// vanished object paired with an appeared one that looks alike as one object moved
/// (analysis/moves.h). The defaults are the recommended settings (analysis/change_preset.h).

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include "chronomap/analysis/change_preset.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// What happened to an object between the two states.
enum class ObjectChange : uint8_t {
  Appeared,  ///< there only in the later state
  Vanished,  ///< there only in the earlier state
  Moved,     ///< a vanished and an appeared object that look alike: one object moved
};
/// "appeared", "vanished", "moved".
const char* toString(ObjectChange kind);

/// Where one half of a move stood: its component's voxels, centroid and size.
struct ObjectPlace {
  uint64_t voxels = 0;
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();  ///< the bounding box's extent per axis
};

/// One changed object.
struct ChangedObject {
  uint32_t id = 0;  ///< 1.. in order of decreasing voxels (ties: the lower component id first)
  ObjectChange kind = ObjectChange::Appeared;
  /// Its changed voxels; a move's are both places' (what vanished and what appeared).
  uint64_t voxels = 0;
  /// Where it is: an appeared object's place, a vanished object's former place, a move's new
  /// place (`to`).
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d bbox_min_m = Eigen::Vector3d::Zero();  ///< of that place
  Eigen::Vector3d bbox_max_m = Eigen::Vector3d::Zero();  ///< of that place
  /// The mean colour of its hits there (a vanished object: as the earlier state saw it).
  Rgb mean_colour;
  /// Moves only: the place it left and the place it took, and the distance between their
  /// centroids in metres.
  ObjectPlace from;
  ObjectPlace to;
  double distance_m = 0.0;
  /// The segmentation's components it is made of (ids): one; a move's vanished, then appeared.
  std::vector<uint32_t> components;

  /// bbox_max_m - bbox_min_m.
  Eigen::Vector3d size_m() const { return bbox_max_m - bbox_min_m; }
};

/// The answer: the diff, its components and the objects they form.
struct Changes {
  DiffMap diff;
  Segmentation segmentation;
  std::vector<ChangedObject> objects;
  uint64_t appeared_voxels = 0;  ///< changed voxels of the diff that appeared
  uint64_t vanished_voxels = 0;  ///< and that vanished
};

/// The objects a segmentation's components form: a component per object, but for the moves
/// pairMoves() finds with `moves`, which become one object each.
/// @throw UsageError for bad settings.
std::vector<ChangedObject> changedObjects(const Segmentation& segmentation, const MoveSettings& moves = {});

/// The changes a diff holds: segmented with settings.segment, objects with settings.moves
/// (settings.diff is not used: the diff was made already).
/// @throw UsageError for bad settings.
Changes changesOf(DiffMap diff, const ChangeSettings& settings = recommendedChangeSettings());

/// What changed from `before` to `after` (two session maps).
/// @throw UsageError for bad settings or maps of different resolutions.
Changes findChanges(const SessionMap& before, const SessionMap& after,
                    const ChangeSettings& settings = recommendedChangeSettings());

/// What changed in a 4D map from its state at `t0_s` to its state at `t1_s` (diff(map, t0, t1)).
/// @throw UsageError for bad settings or times.
Changes findChanges(const TemporalMap& map, double t0_s, double t1_s,
                    const ChangeSettings& settings = recommendedChangeSettings());

/// The objects as JSON, the one form every front door prints: a list of
/// {"id", "kind", "voxels", "centroid" [x, y, z] (m), "size" [x, y, z] (m), "bbox_min", "bbox_max",
/// "colour" [r, g, b], "components" [ids]}, and for a move also "from" and "to" (each {"voxels",
/// "centroid", "size"}) and "distance_m".
nlohmann::json changedObjectsJson(const std::vector<ChangedObject>& objects);

/// The settings as JSON: {"diff": {"mode", "alpha", "neighbourhood_voxels", "min_shift_voxels", "shift_plane_ratio",
/// "kept_surface_radius_voxels", "kept_surface_share", "dark_surface_radius_voxels",
/// "dark_surface_brightness", "dark_surface_contrast", "dark_surface_share", "seen_at_both"}, "segment":
/// {"connectivity", "min_voxels", "colour_tolerance", "min_value"}, "moves": {"pair",
/// "max_size_ratio", "max_height_difference_m", "max_colour_distance", "alike_footprints"}}.
nlohmann::json changeSettingsJson(const ChangeSettings& settings);

}  // namespace chronomap
