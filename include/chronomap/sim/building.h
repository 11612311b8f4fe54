#pragma once
/// @file
/// The simulated building: an office floor recorded by a patrolling robot over many sessions,
/// with every change known. Scenes are boxes (walls, doors, furniture, people), rendered by
/// ray casting through a bounding-volume hierarchy into Kinect-like RGB-D frames.

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/core/image.h"
#include "chronomap/octree/session_map.h"

namespace chronomap::sim {

/// What an object is; change processes act by kind.
enum class ObjectKind : uint8_t { Floor, Wall, Door, Desk, Chair, Shelf, Table, Box, Person, Robot };
/// "floor", "wall", "door", ...
const char* toString(ObjectKind kind);

/// One axis-aligned box of an object with a colour per face (-x, +x, -y, +y, -z, +z).
struct Part {
  Eigen::AlignedBox3d box;
  std::array<Rgb, 6> face_colors;
};

/// An object of the scene. Its parts are in world coordinates for the current state.
struct Object {
  uint32_t id = 0;
  ObjectKind kind = ObjectKind::Box;
  int room = -1;  ///< index into Scene::rooms, -1 for the corridor or the building
  bool present = true;
  std::vector<Part> parts;
};

/// A room's floor area (z = 0) and its door.
struct Room {
  std::string name;           ///< "office 3", "kitchen", "meeting room", "corridor"
  Eigen::AlignedBox2d area;   ///< inside the walls
  Eigen::Vector2d door_m;     ///< centre of the door opening, on the wall to the corridor
  Eigen::Vector2d inside_m;   ///< where the robot stands to look around
  uint32_t door_object = 0;   ///< id of the door
};

/// The state of the building during one session.
struct SceneState {
  std::vector<Object> objects;
  std::vector<Room> rooms;
  Eigen::AlignedBox3d bounds;
};

/// One change between consecutive sessions, with the voxels of the ground truth it changes.
struct ChangeEvent {
  uint32_t object = 0;
  ObjectKind object_kind = ObjectKind::Box;
  std::string kind;  ///< "door_opened", "door_closed", "moved", "added", "removed", "appeared", "left"
  std::vector<VoxelKey> voxels;  ///< truth voxels whose occupancy differs because of it
};

/// Settings of a simulation. Presets: "tiny" (one room), "office" (three rooms and a corridor,
/// the demo), "floor66" (40 x 20 m, 16 rooms, 66 sessions over 45 days).
struct SimulationSettings {
  std::string preset = "office";
  uint64_t seed = 1;
  int sessions = 0;               ///< 0: the preset's default
  double resolution_scale = 1.0;  ///< image size relative to 640 x 480 (0.25 .. 1)
  double voxel_resolution_m = 0.05;  ///< of the ground-truth occupancy
  double noise_per_m2 = 0.0014;   ///< depth noise sigma = this * z^2 (metres); 0 = none
  double localisation_offset_m = 0.02;   ///< sigma of the per-session position offset
  double localisation_yaw_deg = 0.3;     ///< sigma of the per-session heading offset
  double drift_per_frame_m = 0.002;      ///< sigma of the position random walk per frame
  int threads = 0;                ///< 0: all cores
};

/// Pinhole camera in the optical frame (x right, y down, z forward).
struct Camera {
  uint32_t width = 640, height = 480;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};
/// The Kinect-like camera: 57 degrees horizontal field of view, 640 x 480 times `scale`.
Camera kinectCamera(double scale = 1.0);

/// Depth sensor model.
struct SensorModel {
  double noise_per_m2 = 0.0014;  ///< sigma = noise * z^2, metres
  double min_range_m = 0.5, max_range_m = 5.0;
  double depth_scale = 5000.0;   ///< units per metre in the depth PNG (TUM)
  double edge_dropout = 0.5;     ///< probability of losing a pixel at a depth edge
  double dark_dropout = 0.6;     ///< probability of losing a pixel on a dark surface
  double dark_luminance = 40.0;  ///< surfaces darker than this (0..255) are "dark"
};

/// One rendered frame: what the sensor recorded, and the noise-free depth (metres, 0 = no hit).
struct RenderedFrame {
  ImageRgb rgb;
  ImageU16 depth;
  std::vector<float> true_depth_m;
};

/// Ray caster over a scene state: a bounding-volume hierarchy over the present parts.
class Renderer {
 public:
  explicit Renderer(const SceneState& state);
  /// Distance along a unit ray to the nearest part, its face colour; false when nothing is hit.
  bool cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double& t, Rgb& color) const;
  /// Renders one frame. `hour` (0..24) sets the lighting colour; `seed` the noise.
  RenderedFrame render(const Camera& camera, const Eigen::Isometry3d& T_world_camera, const SensorModel& sensor,
                       double hour, uint64_t seed) const;

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    uint32_t first = 0, count = 0;  // parts (leaf) or, when count == 0, children first, first + 1
  };
  std::vector<Part> parts_;
  std::vector<Node> nodes_;
  void build(uint32_t node, uint32_t begin, uint32_t end);
};

/// The lighting colour multiplier at an hour of the day (warm mornings, cool evenings).
Eigen::Vector3d lightingAt(double hour);

/// The building of a preset in its first session's state.
SceneState makeScene(const std::string& preset, uint64_t seed);
/// Applies one session's change processes to `state`; returns the changed object ids with
/// their event kinds. A session may have no change at all.
std::vector<std::pair<uint32_t, std::string>> applyChanges(SceneState& state, uint64_t seed, int session);
/// Unit voxels that overlap a present part, parts being solid (the ground-truth occupancy),
/// sorted in Morton order.
std::vector<VoxelKey> truthOccupancy(const SceneState& state, const KeyGrid& grid);
/// The same for one object.
std::vector<VoxelKey> objectVoxels(const Object& object, const KeyGrid& grid);

/// How well a map's occupied voxels match the ground truth.
struct OccupancyScore {
  size_t predicted = 0;      ///< occupied unit voxels of the map
  size_t truth_known = 0;    ///< truth voxels the map observed (free or occupied)
  size_t true_positive = 0;  ///< occupied in both
  double precision = 0.0;    ///< true_positive / predicted
  double recall = 0.0;       ///< true_positive / truth_known
};
/// Scores `map` against truth voxels sorted in Morton order (truthOccupancy's order).
OccupancyScore scoreOccupancy(const SessionMap& map, const std::vector<VoxelKey>& truth);

/// What simulate() wrote.
struct SimulationSummary {
  std::vector<std::filesystem::path> session_dirs;
  std::vector<double> times_s;
  std::vector<double> hours;
  size_t frames = 0;
  size_t events = 0;
  double seconds = 0.0;
};

/// Progress: (sessions done, sessions in all).
using SimulationProgress = std::function<void(size_t, size_t)>;

/// Simulates and writes `out`: session_NN/ TUM folders (rgb/, depth/, rgb.txt, depth.txt,
/// groundtruth.txt = true poses, trajectory.txt = estimated poses, camera-intrinsics.txt),
/// truth/ (objects_NN.json and occupancy_NN.cmap per session), and scene.json (settings,
/// sessions and every change event). The same settings give byte-identical output.
/// @throw UsageError for an unknown preset or bad settings; IoError when writing fails.
SimulationSummary simulate(const SimulationSettings& settings, const std::filesystem::path& out,
                           const SimulationProgress& progress = {});

}  // namespace chronomap::sim
