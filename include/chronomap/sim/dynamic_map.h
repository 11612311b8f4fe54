#pragma once
/// @file
/// Sequences in the public dynamic-map benchmark's format (docs/benchmarks.md, "Dynamic points"):
/// SEQ/pcd/NNNNNN.pcd, each frame's points in the world frame with the sensor pose in its
/// VIEWPOINT (tx ty tz qw qx qy qz), and SEQ/gt_cloud.pcd, points labelled by their intensity
/// (0 static, 1 dynamic). `chronomap simulate --format dynamic-map` writes one of the box room
/// with people walking through it; bench/dynamic_eval --make-real one of a real recording with
/// people inserted by depth.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/file.h"
#include "chronomap/core/frame.h"
#include "chronomap/sim/box_room.h"

namespace chronomap {

/// A person walking back and forth on a straight line at a steady speed: a box of a person's
/// size standing on the floor, axis-aligned in the world frame.
struct Walker {
  Eigen::Vector3d from_m, to_m;  ///< the ends of the walk, at the box's bottom centre
  double speed_mps = 1.0;
  double start_m = 0.0;          ///< distance walked at time 0 (apart, walkers are out of step)
  Eigen::Vector3d size_m{0.45, 0.3, 1.75};  ///< box extents along the world axes
};

/// The walker's box at `time_s` (back and forth between from_m and to_m).
Box walkerBox(const Walker& walker, double time_s);

/// Writes frames as a dynamic-map sequence, one at a time.
class DynamicMapWriter {
 public:
  /// Writes into a staging folder beside `folder`, moved into place by finish() (pcd/ and
  /// gt_cloud.pcd replace what `folder` had; nothing changes there when finish() is not reached).
  /// Every `gt_stride`-th valid point of the frames (in order) goes to gt_cloud.pcd.
  /// @throw IoError when the staging folder cannot be created.
  DynamicMapWriter(const std::filesystem::path& folder, size_t gt_stride);
  ~DynamicMapWriter();
  DynamicMapWriter(const DynamicMapWriter&) = delete;
  DynamicMapWriter& operator=(const DynamicMapWriter&) = delete;
  /// Writes frame number frames() as pcd/NNNNNN.pcd: its valid points (not NaN) in the world frame,
  /// binary, its pose as VIEWPOINT. `dynamic` (one entry per point, or empty: all static) labels them.
  void add(const Frame& frame, const std::vector<uint8_t>& dynamic);
  /// Writes gt_cloud.pcd (x y z intensity, binary) and moves the sequence into place. Call once,
  /// after the last frame.
  void finish();
  size_t frames() const { return frames_; }
  uint64_t points() const { return points_; }
  uint64_t dynamicPoints() const { return dynamic_points_; }
  size_t gtPoints() const { return gt_.points.size(); }
  size_t gtDynamic() const;

 private:
  std::unique_ptr<StagedFolder> staged_;
  std::filesystem::path folder_;  // the staging folder
  size_t gt_stride_;
  size_t frames_ = 0;
  uint64_t points_ = 0, dynamic_points_ = 0;
  PointCloud gt_;
  std::vector<float> gt_labels_;
};

/// Settings of simulateDynamicMap.
struct DynamicMapSimSettings {
  uint64_t seed = 1;
  size_t frames = 60;
  size_t people = 3;
  double frame_rate_hz = 10.0;
  /// Cameras of the sensor: a ring of this many around one origin, each covering 360 / cameras
  /// degrees (plus a little overlap), so that every frame sees all round as the benchmark's
  /// laser scanners do; 1: one Kinect-like camera (57 degrees) turning twice round in the sequence.
  size_t cameras = 6;
  /// Image size of each camera relative to 640 x 480.
  double resolution_scale = 0.25;
  /// Depth noise sigma = noise * z^2, metres (renderFrame's).
  double noise_per_m2 = 0.0014;
  /// Every this many-th point of the union goes to gt_cloud.pcd.
  size_t gt_stride = 4;
};

/// What simulateDynamicMap wrote.
struct DynamicMapSimSummary {
  size_t frames = 0;
  uint64_t points = 0, dynamic_points = 0;
  size_t gt_points = 0, gt_dynamic = 0;
  double seconds = 0.0;
};

/// The people of the box room for a seed: walks between random points of the floor, away from
/// the camera's circle, at 0.6 to 1.4 m/s.
std::vector<Walker> roomWalkers(const BoxRoom& room, size_t people, uint64_t seed);

/// Writes a dynamic-map sequence of the default box room (defaultRoom) with `people` walking
/// through it: the sensor moves on a 0.3 m circle in the middle of the room at 1.2 m height,
/// turning twice round. Same settings, same bytes. `progress` gets (frames done, frames).
/// @throw UsageError for settings out of range; IoError when the folder cannot be written.
DynamicMapSimSummary simulateDynamicMap(const DynamicMapSimSettings& settings, const std::filesystem::path& folder,
                                        const std::function<void(size_t, size_t)>& progress = {});

/// The dynamic-map benchmark's scores of a cleaned map against a labelled ground truth, as its
/// scripts compute them (export_eval_pcd, evaluate_all): a ground-truth point is kept when the
/// map's nearest point lies within `radius_m` (distance <= radius, in single precision).
struct StaticMapScores {
  size_t static_total = 0, dynamic_total = 0;  ///< ground-truth points labelled 0 and 1
  size_t static_kept = 0, dynamic_removed = 0;
  size_t unlabelled = 0;  ///< labels other than 0 and 1: counted in neither
  /// SA: kept static / static; DA: removed dynamic / dynamic (1 when there are none of a kind).
  double staticAccuracy() const;
  double dynamicAccuracy() const;
  double associatedAccuracy() const;  ///< AA = sqrt(SA * DA)
  double harmonicAccuracy() const;    ///< HA = 2 SA DA / (SA + DA), 0 when both are 0
};

/// The scores of `map` against `truth` labelled by `labels` (one per point: 0 static, 1
/// dynamic), looking points up in a hash of cells of `radius_m`. `kept`, when given, gets one
/// entry per ground-truth point: 1 where the map keeps it (the benchmark's exported labels, inverted).
/// @throw UsageError when the labels do not match the truth's points or the radius is not positive.
StaticMapScores scoreStaticMap(const PointCloud& truth, const std::vector<float>& labels, const PointCloud& map,
                               double radius_m = 0.05, std::vector<uint8_t>* kept = nullptr);
/// The same by comparing every pair of points: the slow reference of the tests.
StaticMapScores scoreStaticMapBruteForce(const PointCloud& truth, const std::vector<float>& labels,
                                         const PointCloud& map, double radius_m = 0.05);

}  // namespace chronomap
