#pragma once
/// @file
/// Navigation costs for a ground robot from a map of occupancy probabilities (a snapshot, or a
/// prediction of the temporal models at some time): a 2D grid over a height band whose cost
/// rises with the predicted occupancy and with how often the space changes, inflated by the
/// robot's radius, and an A* planner on it (export/map_server.h writes it for ROS).
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "chronomap/analysis/rhythm.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// How costmap() reads a map.
struct CostmapSettings {
  double z_min_m = 0.05;         ///< the height band the robot occupies (above the floor)
  double z_max_m = 1.8;
  double robot_radius_m = 0.3;   ///< cells this close to a lethal cell cannot hold the robot's centre
  /// Weight of how often a column's voxels changed (0..1 of their observations) against the
  /// probability of occupancy.
  double change_weight = 0.5;
  /// A column is lethal where a voxel's probability of occupancy exceeds this; below it, the
  /// probability raises the cost in proportion. Above 0.5, space that is as likely free as not
  /// (a door open half the time at that hour) stays passable at a high cost.
  double lethal_probability = 0.5;
  /// With `models`: a modelled voxel (one that changed while learning) is an obstacle only when
  /// the learning sessions saw it occupied at least this often (round(mean x observations)); a
  /// voxel seen occupied fewer times (a stray hit: a flying pixel, depth noise) has its probability
  /// held at lethal_probability, passable at a high cost. 0 or 1: off (the default). Voxels that
  /// never changed, and maps without models, are read as before.
  uint32_t min_occupied_sessions = 0;
};

/// A 2D grid of costs in the map_server convention: -1 unknown, 0 free .. 100 lethal. Cell (i, j)
/// covers x in [origin + i r, origin + (i + 1) r), y likewise; row 0 is the lowest y.
struct Costmap {
  static constexpr int8_t kUnknown = -1, kLethal = 100, kInscribed = 99;
  double resolution_m = 0.05;
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();
  int width = 0, height = 0;
  std::vector<int8_t> cost;  ///< width * height, row-major from the lowest y

  int8_t at(int i, int j) const { return cost[static_cast<size_t>(j) * static_cast<size_t>(width) + static_cast<size_t>(i)]; }
  int8_t& at(int i, int j) { return cost[static_cast<size_t>(j) * static_cast<size_t>(width) + static_cast<size_t>(i)]; }
  /// The cell containing (x, y), if inside.
  std::optional<Eigen::Vector2i> cellOf(const Eigen::Vector2d& p) const;
  Eigen::Vector2d centerOf(const Eigen::Vector2i& c) const;
};

/// The costs of `map` over the settings' band: a column is lethal when a voxel in the band is
/// likely occupied (P > lethal_probability), else it costs its highest probability and its voxels' change share
/// (`models`, when given: the share of each voxel's learning observations that differ from the
/// one before), scaled into 0..98 (settings.min_occupied_sessions holds back modelled voxels seen
/// occupied too rarely); unknown when the band holds no known voxel; then every cell
/// within the robot's radius of a lethal cell becomes kInscribed.
/// @throw UsageError for an empty band or a negative radius.
Costmap costmap(const SessionMap& map, const CostmapSettings& settings, const RhythmModels* models = nullptr);

/// Marks every cell whose centre lies within `radius_m` of a lethal cell's centre kInscribed
/// (lethal cells stay lethal). costmap() ends with it. Time and memory are linear in the grid,
/// whatever the radius (an exact Euclidean distance transform).
void inflate(Costmap& costmap, double radius_m);

/// A* on the costmap between two cells: 8-connected, a step costs its length times
/// (1 + cost / 25); unknown, inscribed and lethal cells are not entered (the start is).
/// @return the cells from start to goal, or nothing when the goal cannot be reached.
std::optional<std::vector<Eigen::Vector2i>> planPath(const Costmap& costmap, const Eigen::Vector2i& start,
                                                     const Eigen::Vector2i& goal);

}  // namespace chronomap
