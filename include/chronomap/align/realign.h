#pragma once
/// @file
/// Re-alignment of a session map against a consensus map (thesis §2.2): voxel data that the
/// localisation error put one or two voxels away from where every other recording saw it is
/// moved back, so that it is not stored as change.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Parameters of re-alignment. The score of moving a voxel's data next to a consensus voxel is
///   s = 1 / (d^ωd · c^ωc · p^ωp)
/// with d the distance between the two voxel centres in voxels, c the distance of their mean
/// colours with each channel scaled to 0..1 (0..√3), p the difference of their occupancy
/// probabilities (0..1); each term is raised to at least `epsilon` first, so identical voxels
/// score a finite 1 / (d^ωd · ε^(ωc+ωp)). The thesis used α = 2 and all weights 1 in units it
/// does not state; the defaults here come from bench/realign_eval (docs/realign.md).
struct RealignSettings {
  double alpha = 1000.0;             ///< a move needs a score above this
  double weight_distance = 1.0;      ///< ωd
  double weight_colour = 1.0;         ///< ωc
  double weight_probability = 1.0;   ///< ωp
  double max_distance_voxels = 1.0;  ///< d_max: candidates lie within this Euclidean distance
  double epsilon = 0.01;             ///< least value of each term (keeps the score finite)
  /// The consensus counts as occupied above this probability. 0.5 is the thesis' rule, but
  /// summed counters make a voxel occupied once about 4% of the rays through it end there, so
  /// the consensus of shifted sessions is the union of their surfaces; a higher value keeps
  /// only what most sessions saw.
  double consensus_occupied_above = 0.5;
  /// What moving a voxel's data does (see realign()).
  enum class Move : uint8_t {
    /// The two voxels exchange their contents; only places where the session is not occupied
    /// can receive. No observation is lost.
    Swap,
    /// The data goes to the new place (added to what the session holds there when that is
    /// occupied, replacing it when free) and the old place becomes unobserved, which the 4D
    /// map never reads as a change. Any consensus-occupied place can receive.
    Transfer,
  };
  Move move = Move::Transfer;

  /// True when the consensus counters `c` count as occupied under consensus_occupied_above.
  bool consensusOccupied(const VoxelCounters& c) const {
    return c.state() != VoxelState::Unknown && c.probability() > consensus_occupied_above;
  }
  /// @throw UsageError for negative, non-finite or out-of-range values (d_max above 8 voxels,
  /// a consensus probability outside [0.5, 1)).
  void validate() const;
};

/// The score of a pair, as defined above. Finite for any finite non-negative input.
double realignScore(double distance_voxels, double colour_distance, double probability_difference,
                    const RealignSettings& settings);
/// c of the score: Euclidean distance of two colours with channels scaled to 0..1.
double colourDistance(const Rgb& a, const Rgb& b);
/// The score of moving the data `moved` (of the session) by `distance_voxels` to a place where
/// the consensus holds `consensus_there`.
double realignScore(const VoxelCounters& moved, const VoxelCounters& consensus_there, double distance_voxels,
                    const RealignSettings& settings);

/// One move: the session's data at `from` went to `to`, and the data at `to` (free space or
/// nothing) went to `from`.
struct RealignMove {
  VoxelKey from, to;
  double score = 0.0;
  bool occupied_pass = true;  ///< found by the first pass (else the second)
  friend bool operator==(const RealignMove&, const RealignMove&) = default;
};

/// What realign() did.
struct RealignReport {
  size_t occupied_disagreeing = 0;  ///< occupied in the session, free in the consensus
  size_t free_disagreeing = 0;      ///< free in the session, occupied in the consensus
  size_t moved_occupied = 0;        ///< moves of the first pass
  size_t moved_free = 0;            ///< moves of the second pass
  std::vector<RealignMove> moves;   ///< in the order they were found
  size_t moved() const { return moved_occupied + moved_free; }
};

/// Re-aligns `session` against `consensus` (same resolution; normally a consensus that
/// includes the session) in the thesis' two passes over the voxels whose occupied/free state
/// disagrees (the consensus counting as occupied above `consensus_occupied_above`), each in
/// Morton order of its keys:
///  1. a voxel occupied in the session and not in the consensus: among the places within d_max
///     where the consensus is occupied (and, for Move::Swap, the session is not), the
///     best-scoring one (the session's data here against the consensus there) receives its
///     data if the score exceeds α;
///  2. a voxel free in the session and occupied in the consensus: among the session's occupied
///     voxels within d_max, the best-scoring one (its data against the consensus here) gives
///     its data to this voxel if the score exceeds α.
/// Each voxel takes part in one move at most; moves are decided on the original session. Ties
/// go to the candidate with the smaller Morton code.
/// @throw UsageError for different resolutions or bad settings.
SessionMap realign(const SessionMap& session, const SessionMap& consensus, const RealignSettings& settings = {},
                   RealignReport* report = nullptr);

}  // namespace chronomap
