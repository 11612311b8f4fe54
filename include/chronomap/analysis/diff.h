#pragma once
/// @file
/// Differencing of maps (thesis §3.1): what changed between two session maps, a session map and
/// a time of a 4D map, or two times of one 4D map.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// How two observations of a voxel are compared (DESIGN.md "Differencing").
enum class DiffMode : uint8_t {
  Hard = 0,        ///< occupied <-> free changes only; unknown on either side is no change
  Threshold = 1,   ///< |P1 - P2| > alpha, both known
  Band = 2,        ///< hard, but P within 0.5 +- alpha counts as unknown
  Continuous = 3,  ///< |P1 - P2| for every voxel known in both
};

/// "hard", "threshold", "band", "continuous".
const char* toString(DiffMode mode);
/// Parses a mode name. @throw UsageError naming the accepted names.
DiffMode parseDiffMode(const std::string& name);

/// Settings of a diff.
struct DiffSettings {
  DiffMode mode = DiffMode::Hard;
  /// The threshold of Threshold mode (probability difference) and the half width of Band
  /// mode's grey band around 0.5. Ignored by Hard and Continuous. A negative value picks the
  /// mode's default: kDefaultThresholdAlpha or kDefaultBandAlpha.
  double alpha = -1.0;
  /// > 0: a voxel that appeared is no change when the first map holds an occupied voxel within
  /// this many voxels (Chebyshev distance), and one that vanished is none when the second map
  /// does: a surface seen a voxel or two away, as a localisation error of a few centimetres
  /// makes it, is not a change. 0 (the default) compares each voxel with its twin only, as
  /// §3.1 defines. Unit cells only; Continuous mode ignores it.
  int neighbourhood_voxels = 0;
  /// With neighbourhood_voxels > 0: a voxel that rule would drop is still a change when the
  /// surface around it moved by at least this many voxels. Each map's surface position is the
  /// mean position of the hits within the neighbourhood (Chebyshev distance
  /// neighbourhood_voxels), over the voxels known in both maps; every voxel keeps where in it
  /// its rays ended (VoxelCounters::offset), so the position is good to a fraction of a voxel
  /// and a surface shifted by a centimetre of pose error is told from an object moved by a few
  /// centimetres. (Maps written without hit positions place each hit at its voxel's centre.)
  /// Where either side has no hits there, the rule drops the voxel as before. 0 (the default):
  /// the rule drops every voxel near a surface.
  double min_shift_voxels = 0.0;
  /// The recommended min_shift_voxels for registered sessions: a surface moved by half a voxel.
  static constexpr double kRecommendedMinShift = 0.5;
  /// > 0: the shift test measures a flat surface's move across it only. The voxels with hits
  /// within the neighbourhood that both maps know, each at its hits' mean position, give a plane:
  /// each map's points are taken about their own mean (so the move being measured does not tilt
  /// it) and their spreads pooled (the eigenvalues of the pooled covariance). Where the least
  /// spread is at most this share of the middle one, the middle one at least a tenth of the
  /// largest (not points along a line) and each map has hits in at least three of those voxels,
  /// the shift is the part of the move along the plane's normal. A flat surface seen from
  /// another place, at a grazing angle or measured deeper (a glossy table top), or sampled on
  /// another part of it, moves its hits' mean along itself without having moved. Elsewhere (most
  /// corners, poles and rows of voxels, surfaces whose shape differs between the maps) the whole
  /// move counts. 0 (the default): the whole move always, as before. In [0, 1].
  double shift_plane_ratio = 0.0;
  /// The recommended shift_plane_ratio, chosen on the simulated office's training seeds (both
  /// sensors, docs/changes.md): a plane's rms thickness under 0.39 of its rms width.
  static constexpr double kRecommendedShiftPlaneRatio = 0.15;
  /// > 0: the weak-change rule. A voxel that appeared is no change when the first map holds
  /// occupied voxels within this many voxels (Chebyshev) and at least kept_surface_share of
  /// them are occupied in the second map as well, with the mean position of their hits less than
  /// half a voxel from where it was (and a voxel that vanished likewise, the maps' roles
  /// swapped): the surface that was there is still seen, unchanged, by the later session,
  /// so the new "surface" in front of it is the same surface measured at another depth by part
  /// of that session's frames (dark, glossy materials: docs/changes.md), not an object. An
  /// object put in front of a surface hides part of it from the later session (unknown there)
  /// and one that moved leaves free space behind or moves its hits, so each keeps its voxels.
  /// Applied after the neighbourhood rule, to unit cells; Continuous mode ignores it. 0 (the
  /// default): off.
  int kept_surface_radius_voxels = 0;
  /// The share of the first map's occupied voxels around a voxel that the weak-change rule needs
  /// still occupied in the second map, in (0, 1].
  double kept_surface_share = kDefaultKeptSurfaceShare;
  static constexpr double kDefaultKeptSurfaceShare = 0.9;
  /// The recommended kept_surface_radius_voxels: 3 voxels (15 cm at 5 cm), the depth errors
  /// seen on the real frames are up to 13 cm.
  static constexpr int kRecommendedKeptSurfaceRadius = 3;
  /// > 0: the dark-surface rule. Active depth cameras measure dark surfaces (little light
  /// returned) with errors far beyond their noise elsewhere: on the 3DMatch study room the same
  /// dark sofa is measured 8 to 12 cm apart by frames that agree within 5 mm on bright surfaces
  /// (docs/changes.md). The rule judges objects, not voxels: the changed unit cells of one kind
  /// that touch (26-neighbourhood, as vertex connectivity) form an object, and an object is no
  /// change when (1) every one of its voxels has an occupied voxel of the other map within this
  /// many voxels (Chebyshev): the object is a layer along a surface the other map sees, no
  /// thicker than the depth error, and (2) at least dark_surface_share of its voxels are dark
  /// (the mean colour of their hits under dark_surface_brightness: the second map's hits for an
  /// object that appeared, the first map's for one that vanished) and darker than
  /// dark_surface_contrast times the other map's surface around them. So a dark surface seen up
  /// to this far in front of or behind the other map's is that surface measured at another depth,
  /// while a dark object standing on a lighter floor, which reaches farther from the floor than
  /// the radius, stays a change whole. Its price: a dark object no thicker than the radius along a
  /// lighter surface (a dark mat on a light floor, a dark bag against a light wall) is no change
  /// either. Needs colour: a voxel whose hits carry none (every colour sum zero, with no coloured
  /// voxel within the radius in the same map, as in maps integrated without colour) is never
  /// dark. Applied after the weak-change rule, to unit cells (an object's cubes, if any, neither
  /// count nor are dropped); Continuous mode ignores it. 0 (the default): off.
  int dark_surface_radius_voxels = 0;
  /// The brightness below which the dark-surface rule calls a voxel's surface dark: the mean
  /// of its hits' red, green and blue (0..255), in [0, 255]. 0 makes nothing dark.
  double dark_surface_brightness = kDefaultDarkSurfaceBrightness;
  static constexpr double kDefaultDarkSurfaceBrightness = 40.0;
  /// The dark-surface rule needs the voxel's surface darker than this share of the brightness
  /// of the other map's surface around it (its occupied voxels within the radius, by their hits),
  /// in (0, 1]: the view that measured it returned little light (the 3DMatch sofa: 27 against 72
  /// for the same place). A dark object moved under the same light looks as dark in both maps
  /// and stays a change (the simulated office's black chairs). 1 drops the condition.
  double dark_surface_contrast = kDefaultDarkSurfaceContrast;
  static constexpr double kDefaultDarkSurfaceContrast = 0.6;
  /// The share of an object's voxels the dark-surface rule needs dark and darker than the other
  /// map's surface around them, in (0, 1]: half (the 3DMatch sofa's displaced patches: 76 %).
  double dark_surface_share = kDefaultDarkSurfaceShare;
  static constexpr double kDefaultDarkSurfaceShare = 0.5;
  /// The dark_surface_radius_voxels measured on the 3DMatch room and floor66 (docs/changes.md): at 3
  /// the dark chairs floor66 sees only near the floor are dropped.
  static constexpr int kDarkSurfaceRadius = 2;
  /// 4D maps only (diff(map, t1, t2)): compare what the sessions in effect at the two times (the
  /// last at or before each) observed, as a diff of those two session maps does: a voxel's state
  /// at a time counts as unknown unless that session's coverage holds the voxel (a cube: all of
  /// it), for the rules' neighbourhoods too. false (the default): each voxel as last observed up
  /// to each time, so a change no session between saw shows up at the first session that did,
  /// and a surface last seen weeks ago still counts as the neighbour of a change.
  bool seen_at_both = false;

  /// Threshold mode's default: a voxel must move by more than 0.4 in probability, so a free
  /// voxel (P near 0) must become clearly occupied (P > 0.4) to count.
  static constexpr double kDefaultThresholdAlpha = 0.4;
  /// Band mode's default: probabilities in (0.4, 0.6) are too uncertain to call.
  static constexpr double kDefaultBandAlpha = 0.1;

  /// alpha with the default applied.
  double effectiveAlpha() const;
  /// @throw UsageError for an alpha that is not finite, or not in [0, 1) (threshold) or
  /// [0, 0.5) (band), a neighbourhood outside 0..4, a min_shift_voxels that is not finite or is
  /// negative, a shift_plane_ratio outside [0, 1], a kept_surface_radius_voxels outside 0..4, a
  /// kept_surface_share outside (0, 1], a dark_surface_radius_voxels outside 0..4 or a
  /// dark_surface_brightness outside [0, 255].
  void validate() const;
};

/// What happened to a changed cell, from the first map to the second.
enum class ChangeKind : uint8_t {
  Appeared = 1,   ///< more occupied in the second map (free -> occupied, or P rose)
  Vanished = 2,   ///< less occupied in the second map (occupied -> free, or P fell)
  Unchanged = 3,  ///< Continuous mode only: known in both with the same probability
};
/// "appeared", "vanished", "unchanged".
const char* toString(ChangeKind kind);

/// One cell of a diff: a unit voxel (level 0) or a uniform cube of 2^level voxels per axis.
struct ChangeCell {
  VoxelKey key;     ///< lower corner
  uint8_t level = 0;
  ChangeKind kind = ChangeKind::Appeared;
  /// Mean colour of the occupied side (the new surface for Appeared, the vanished one for
  /// Vanished; for Continuous, the side with hits, the second map preferred). Black without.
  Rgb colour;
  /// |P1 - P2|.
  float value = 0.0f;
  friend bool operator==(const ChangeCell&, const ChangeCell&) = default;
};

/// Work a 4D diff did, for benchmarks.
struct DiffStats {
  size_t inner_nodes_visited = 0;
  size_t lists_compared = 0;
};

/// The output of a diff: a sparse linear octree, i.e. its cells sorted by the Morton code of
/// their lower corner, non-overlapping. Hard, Threshold and Band diffs hold changed cells only;
/// a Continuous diff holds every cell known in both maps.
class DiffMap {
 public:
  /// @throw UsageError for a bad resolution.
  explicit DiffMap(double resolution_m = 0.05, DiffSettings settings = {});
  /// Builds a diff from cells in any order.
  /// @throw FormatError when cells overlap or have an impossible level.
  static DiffMap fromCells(double resolution_m, DiffSettings settings, std::vector<ChangeCell> cells);

  const KeyGrid& grid() const { return grid_; }
  double resolution_m() const { return grid_.resolution_m(); }
  const DiffSettings& settings() const { return settings_; }
  /// Cells in Morton order of their corners.
  std::span<const ChangeCell> cells() const { return cells_; }
  bool empty() const { return cells_.empty(); }

  /// Unit voxels in cells of this kind (every kind when `kind` is not given).
  uint64_t voxelCount() const;
  uint64_t voxelCount(ChangeKind kind) const;

  friend bool operator==(const DiffMap&, const DiffMap&);

 private:
  friend DiffMap diff(const SessionMap&, const SessionMap&, const DiffSettings&);
  friend DiffMap diff(const TemporalMap&, double, double, const DiffSettings&, DiffStats*);
  KeyGrid grid_;
  DiffSettings settings_;
  std::vector<ChangeCell> cells_;
};

/// Compares one observation pair (either may be unknown: length and hits zero) under the
/// settings: the cell to record at `key`/`level`, or nothing. The rule every diff applies
/// before the neighbourhood rule.
std::optional<ChangeCell> compareVoxel(const VoxelCounters& before, const VoxelCounters& after,
                                       const DiffSettings& settings);

/// How far the surface near `key` moved from `before` to `after`, in voxels, as
/// DiffSettings::min_shift_voxels measures it: the distance between the mean positions of the
/// hits within `radius_voxels` (Chebyshev) of `key` on each side, over the voxels both maps
/// know (a hit lies at its voxel's centre plus the voxel's mean offset,
/// VoxelCounters::offset); nothing when either side has no hits there. With `plane_ratio` > 0,
/// only the move across a plane, as DiffSettings::shift_plane_ratio says.
/// @throw UsageError for different resolutions, a radius outside 0..4 or a plane ratio outside
/// [0, 1].
std::optional<double> surfaceShift(const SessionMap& before, const SessionMap& after, const VoxelKey& key,
                                   int radius_voxels, double plane_ratio = 0.0);

/// What changed from `before` to `after` (two session maps of the same resolution).
/// @throw UsageError for different resolutions or bad settings.
DiffMap diff(const SessionMap& before, const SessionMap& after, const DiffSettings& settings = {});

/// The neighbourhood rule of `settings` (neighbourhood_voxels, min_shift_voxels, then the
/// weak-change rule, kept_surface_radius_voxels, then the dark-surface rule,
/// dark_surface_radius_voxels) applied to the
/// cells of a diff found with neighbourhood_voxels = 0, reading each side's unit voxels through
/// `before` and `after` (zero counters where unknown). Lets a diff assembled from parts (the
/// tiles of a tiled map) drop the same cells as the diff of the whole. Does nothing in
/// Continuous mode or without a neighbourhood, a kept-surface radius and a dark-surface radius.
void applyNeighbourhoodRule(std::vector<ChangeCell>& cells, const DiffSettings& settings,
                            const std::function<VoxelCounters(const VoxelKey&)>& before,
                            const std::function<VoxelCounters(const VoxelKey&)>& after);

/// What changed in a 4D map from its state at t1_s to its state at t2_s: equal to the diff of
/// the two snapshots. Except in Continuous mode, which must report unchanged voxels too, only
/// the subtrees that hold changes by sessions between the two times are visited.
/// @throw UsageError for bad settings.
DiffMap diff(const TemporalMap& map, double t1_s, double t2_s, const DiffSettings& settings = {},
             DiffStats* stats = nullptr);

}  // namespace chronomap
