#pragma once
/// @file
/// The 4D map: a temporal octree that keeps every observed state of a place (thesis §2.3).

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/coverage.h"

namespace chronomap {

/// When a new observation of a voxel counts as a change from the state valid before it.
/// The occupied/free state always counts; the two thresholds add finer criteria.
struct ChangeCriterion {
  /// > 0: also a change when the occupancy probabilities differ by more than this (0..1).
  double probability_threshold = 0.0;
  /// > 0: also a change when both voxels hold hits and their mean colours lie farther apart
  /// than this (Euclidean distance in 8-bit RGB units, 0..441).
  double colour_distance = 0.0;
  /// > 0: also a change when both voxels hold hits and the mean position of the hits in the
  /// voxel (VoxelCounters::meanOffset) moved farther than this (Euclidean, in voxels, 0..2; 0: off): a
  /// surface that moved by part of a voxel keeps its state, and without a new entry the map would
  /// keep its old position, which the diff's shift test (DiffSettings::min_shift_voxels) reads.
  double surface_shift_voxels = kRecommendedSurfaceShift;
  /// The default: half a voxel, the shift the diff's test calls a move (chosen on the simulated
  /// office's seed 1, docs/changes.md): the 4D map then finds the 9 of 9 events the session maps
  /// find, a chair moved by 37 mm among them (8 of 9 without), for 0.4 % more nodes; on
  /// floor66 (66 sessions) it costs 15.5 % more nodes (258 of 258 events, 257 without).
  static constexpr double kRecommendedSurfaceShift = 0.5;
  /// > 0: a weak observation does not change a voxel's state (hysteresis against sampling noise):
  /// free from less ray length than this through the voxel (metres; a ray that grazed it, no hit)
  /// does not end an occupied state. 0: off (every state change counts).
  double min_free_length_m = 0.0;
  /// > 0: occupied from fewer hits than this does not end a free state (a stray hit), and the
  /// surface-shift test needs at least this many hits on both sides (the mean position of one or
  /// two hits is mostly noise). 0 or 1: off (every hit counts).
  uint32_t min_hits = 0;
  /// True when min_free_length_m or min_hits (above 1) hold observations back. Such a map takes
  /// sessions in time order only (add after the last, remove or replace the last): a session
  /// added before a later one would re-decide that one's entry against the wrong state, since the
  /// map cannot tell a later observation the rule held back from one that confirmed the state.
  bool hasEvidenceRule() const { return min_free_length_m > 0.0 || min_hits > 1; }

  friend bool operator==(const ChangeCriterion&, const ChangeCriterion&) = default;
  /// True when `after` is a change from `before` (both known).
  bool differs(const VoxelCounters& before, const VoxelCounters& after) const;
  /// @throw UsageError for negative or non-finite thresholds.
  void validate() const;
};

/// One entry of a voxel's history: from `time_s` until the next entry, the voxel read as
/// `counters` (for a voxel inside a larger uniform cube: the cube's sums split evenly).
struct HistoryEntry {
  double time_s = 0.0;
  VoxelCounters counters;
  /// Level of the cube the entry is stored for (0 = the voxel itself).
  int level = 0;
};

/// What the 4D map knows about one added session.
struct SessionRecord {
  double time_s = 0.0;
  std::string name;             ///< where it came from (a file name), for people
  uint64_t nodes_separate = 0;  ///< nodes of the session map stored on its own (inner + leaves)
  int64_t nodes_added = 0;      ///< change in the 4D map's node count when it was added
  Coverage coverage;            ///< the voxels it observed
};

/// Options of TemporalMap::add.
struct AddSettings {
  /// Replace a session already stored at the same time instead of refusing.
  bool replace = false;
  /// Name recorded with the session.
  std::string name;
};

/// What one TemporalMap::add did.
struct AddReport {
  size_t entries_added = 0;    ///< history entries created (changes and restored states)
  size_t entries_removed = 0;  ///< entries that became redundant and were dropped
  size_t inner_added = 0;      ///< inner nodes created (new space or refined uniform cubes)
  bool replaced = false;       ///< a session at the same time was replaced
  bool out_of_order = false;   ///< later sessions were already stored
};

/// Node counts of a 4D map. Like the thesis' Figure 3, a "node" is an inner node or one
/// entry of a child slot's time-keyed map.
struct TemporalCounts {
  size_t inner_nodes = 0;
  size_t slots = 0;    ///< child slots that hold a time-keyed map
  size_t entries = 0;  ///< entries in those maps
  size_t nodes() const { return inner_nodes + entries; }
};

/// A temporal octree. Inner nodes hold 8 child references and never go away; a reference is
/// either another inner node or a time-keyed map ("slot list") whose entries give the counters
/// of the child's whole cube from a session on, until the next entry. Lists above unit level
/// describe uniform known-free cubes; when a change reaches inside one, it is refined into 8
/// lists that copy its whole history, so every query stays exact.
///
/// Entries are created only where a session observed a cube and its state changed under the
/// ChangeCriterion; unobserved space adds nothing. Sessions may be added in any time order:
/// the per-session Coverage tells which later session observed a voxel next, so the state seen
/// at every time is that of the most recent observation, exactly as if added in time order
/// (not under the criterion's evidence rule, which takes sessions in time order only).
class TemporalMap {
 public:
  /// One stored entry: the session (rank in time order) and the counters from then on.
  struct Entry {
    uint32_t session = 0;
    VoxelCounters value;
    friend bool operator==(const Entry&, const Entry&) = default;
  };
  using Ref = uint32_t;
  static constexpr Ref kEmpty = 0xffffffffu;
  static constexpr Ref kListBit = 0x80000000u;
  using Children = std::array<Ref, 8>;

  /// @throw UsageError for a bad resolution or criterion.
  explicit TemporalMap(double resolution_m = 0.05, ChangeCriterion criterion = {});

  const KeyGrid& grid() const { return grid_; }
  double resolution_m() const { return grid_.resolution_m(); }
  const ChangeCriterion& criterion() const { return criterion_; }

  /// Adds a session observed at `time_s` (seconds since the epoch).
  /// @throw UsageError for a time checkTime refuses (core/time.h: NaN, or outside the years 1
  /// to 9999, which no command could name), a different resolution, or a time already stored
  /// when options.replace is false.
  AddReport add(double time_s, const SessionMap& session, const AddSettings& options = {});
  /// Removes the session stored at `time_s`, as if it had never been added.
  /// @throw UsageError when no session has that time.
  void remove(double time_s);
  /// Appends sessions, after the last, that observed nothing in this map (their times and names
  /// kept, coverage empty, node counts zero): what a map that no later session reached (a tile
  /// the streaming build left as it was) holds, without rebuilding it. Entries stay as they are.
  /// @throw UsageError for a time not after the previous one.
  void appendUnobservedSessions(const std::vector<SessionRecord>& later);
  /// Replaces the sessions' records (coverage, name, node counts) with `records`, of the same
  /// sessions: as many, at the same times. The history is untouched.
  /// @throw UsageError when the counts or a time differ.
  void replaceSessionRecords(std::vector<SessionRecord> records);

  /// Session times in increasing order.
  std::vector<double> times() const;
  /// Sessions in time order.
  const std::vector<SessionRecord>& sessions() const { return sessions_; }
  size_t sessionCount() const { return sessions_.size(); }

  /// What one snapshot visited (for tests and benchmarks).
  struct SnapshotVisits {
    size_t inner = 0;   ///< inner nodes entered
    size_t lists = 0;   ///< slot lists read
    size_t coarse = 0;  ///< subtrees answered by one coarse entry without descending
  };
  /// The map as most recently observed at `time_s`: every voxel observed by a session at or
  /// before `time_s` carries the entry valid then. Empty before the first session. Known-free
  /// space is compressed as SessionMap::compressFree() compresses it: a cube whose voxels all
  /// read free without hits at `time_s` is one leaf (lengths summed), read from the cube's
  /// coarse entry without visiting the refined subtree below it, so the cost follows the
  /// snapshot's size, not every refinement ever made. The result is bit for bit the expanded
  /// snapshot after compressFree().
  SessionMap snapshot(double time_s, SnapshotVisits* visits = nullptr) const;
  /// snapshot() of a map whose tree is `inner` (checked as fromParts checks it) at a time at
  /// which list i holds `valid[i]` (its entry valid then; none before its first), without the
  /// rest of the histories: the same nodes in the same order (coarse cubes included), for a
  /// reader that decodes one time of a file (store/tiled_file.h). The values are taken as the
  /// map would store them (offsets quantised). @throw FormatError for a tree fromParts refuses
  /// (`valid` holding one value per list) or a value it refuses.
  static SessionMap snapshotOfStates(double resolution_m, const std::vector<Children>& inner,
                                     const std::vector<std::optional<VoxelCounters>>& valid);
  /// The entries of the voxel `key` in time order (empty when it was never observed).
  std::vector<HistoryEntry> history(const VoxelKey& key) const;
  /// Entries valid in the voxel `key` at `time_s`, if any.
  std::optional<VoxelCounters> valueAt(const VoxelKey& key, double time_s) const;

  /// Calls fn(const VoxelKey& corner, int level, uint32_t changes) for every cube whose history
  /// holds at least one change with a time in (t0_s, t1_s]. A change is any entry after the
  /// cube's first (its first observation is not a change).
  template <class Fn>
  void forEachChangeCount(double t0_s, double t1_s, Fn&& fn) const;

  /// Calls fn(const VoxelKey& corner, int level, std::span<const Entry>) for every slot list.
  template <class Fn>
  void forEachList(Fn&& fn) const;
  /// Calls fn(const VoxelKey& corner, int level) for every slot list, in the order forEachList
  /// visits them, without decoding its entries.
  template <class Fn>
  void forEachListPlace(Fn&& fn) const;

  /// Calls fn(const VoxelKey& corner, int level, std::span<const Entry>) for every slot list
  /// that holds a change (an entry after its first) by a session of rank in [first, end).
  /// Subtrees without such a change are skipped by a summary per inner node (a 64-bit mask of
  /// the ranks, modulo 64, of the changes below it), so the cost follows the number of changes
  /// in the range rather than the size of the map. The summary is rebuilt on the first call
  /// after the map was modified (linear in the map; that first call must not run concurrently
  /// with another). @return the number of inner nodes visited.
  template <class Fn>
  size_t forEachListChangedIn(uint32_t first, uint32_t end, Fn&& fn) const;

  /// Rank (index in sessions()) of the last session with a time <= time_s + kTimeSlack_s, or
  /// nothing: chronomap prints times to the millisecond, and a printed time given back names its
  /// session (the printed time may lie up to half a millisecond before it).
  std::optional<uint32_t> rankAtOrBefore(double time_s) const;
  static constexpr double kTimeSlack_s = 0.0005 + 1e-6;
  /// Number of sessions with a time <= time_s: sessions in (t0, t1] have the ranks
  /// [ranksThrough(t0), ranksThrough(t1)).
  uint32_t ranksThrough(double time_s) const {
    const auto r = rankAtOrBefore(time_s);
    return r ? *r + 1 : 0u;
  }

  TemporalCounts counts() const;
  /// Bytes of node storage in use (pools, free blocks included; coverage included).
  size_t memoryBytes() const;
  /// Where memoryBytes() goes, part by part (the parts sum to it).
  struct MemoryUse {
    size_t inner = 0;          ///< inner nodes (8 references each)
    size_t lists = 0;          ///< list records in use (each holds its newest entry)
    size_t entries = 0;        ///< entries of lists with 2 or more, in the arena
    size_t hit_parts = 0;      ///< hits, colours and positions of entries with hits
    size_t slack = 0;          ///< free list records, free room in the arena, free hit parts
    size_t coarse = 0;         ///< coarse entries and spans (issue 28), their marks
    size_t sessions = 0;       ///< session records and coverages
    size_t change_masks = 0;   ///< the change summary of forEachListChangedIn
  };
  MemoryUse memoryUse() const;

  /// When compact() re-lays the pools out.
  enum class Relayout {
    kAlways,      ///< as files hold them, for snapshots of the map in memory
    kWhenMerged,  ///< only when lists were merged: for a map about to be written and dropped
                  ///< (a file's bytes do not depend on the pools' order in memory)
  };
  /// Merges 8 sibling lists with the same sessions and no hits into one (states stay exact;
  /// lengths are summed, as in §2.1's compression) and re-lays the pools out as files hold them.
  /// @return the number of lists removed.
  size_t compact(Relayout relayout = Relayout::kAlways);
  /// True when compact() ran last and nothing changed the map since (add, remove, relayout,
  /// appendUnobservedSessions, replaceSessionRecords): compacting it again would change nothing,
  /// so it returns at once.
  bool isCompact() const { return compact_; }

  /// Re-lays the inner nodes and list records out in place in the order files hold them (see
  /// parts()): what a snapshot of the latest time reads first, depth first, then the subtrees
  /// that coarse entries shadow. Answers stay the same; only the memory layout changes.
  /// add() and remove() call it on their own once the nodes that snapshot reads outside the
  /// block where the last layout put them (created since, or no longer shadowed) reach 1/16 of
  /// what it reads, so that it keeps walking a dense prefix of the pools however many sessions
  /// a map grows through in memory. Costs about a copy of the inner nodes and list records.
  void relayout();
  /// How many times the pools were re-laid out (by relayout(), compact() or add()).
  size_t relayouts() const { return relayouts_; }

  /// A depth-first, gap-free copy of the pools for serialisation.
  struct Parts {
    std::vector<Children> inner;
    std::vector<uint32_t> list_sizes;  ///< in list-index order
    std::vector<Entry> entries;        ///< all lists' entries, one list after another
  };
  Parts parts() const;
  /// Rebuilds a map from parts and session records.
  /// @throw FormatError if they do not form a valid map.
  static TemporalMap fromParts(double resolution_m, ChangeCriterion criterion, Parts parts,
                               std::vector<SessionRecord> sessions);
  /// The level of each of the `lists` lists of the tree `inner`. @throw FormatError unless every
  /// node and list is reached once from the root, no inner node below unit level.
  static std::vector<int> listLevelsOf(const std::vector<Children>& inner, size_t lists);

  /// Same resolution, criterion, sessions and histories (layout may differ).
  friend bool operator==(const TemporalMap& a, const TemporalMap& b);

 private:
  // Entries are stored split (docs/temporal.md, "Layout in memory"): every entry as its session
  // and length, and only entries with hits (or colour) with a part that holds the hits, the
  // colour sums and the mean hit offset quantised as files keep it (core/offset_quantiser.h),
  // so that a map built in memory reads exactly as the same map read back from its file.
  static constexpr uint32_t kNoPart = 0xffffffffu;
  struct Stored {
    uint32_t session = 0;
    float length_m = 0.0f;
    uint32_t part = kNoPart;  // index in hit_parts_, owned by the entry (a list's copy of its newest shares it)
  };
  struct HitPart {
    uint32_t hits = 0, red = 0, green = 0, blue = 0;
    uint8_t offset[3] = {0, 0, 0};
    uint8_t unused = 0;
  };
  struct List {
    Stored first;            // the only entry while size == 1, else a copy of the newest
    uint32_t block = 0;      // arena offset of the entries while size >= 2
    uint16_t size = 0;
    uint8_t capacity_log2 = 0;
    uint8_t unused = 0;
  };
  /// True when store() keeps a hit part for `value`: it has hits or colour.
  static bool keepsHitPart(const VoxelCounters& value) {
    return value.hits != 0 || value.red != 0 || value.green != 0 || value.blue != 0;
  }
  /// An entry as stored (a part taken when keepsHitPart).
  Stored store(uint32_t session, const VoxelCounters& value);
  /// Frees the part of a stored entry that is dropped.
  void release(const Stored& s);
  VoxelCounters valueOf(const Stored& s) const;
  Entry entryOf(const Stored& s) const { return Entry{s.session, valueOf(s)}; }
  bool freeWithoutHits(const Stored& s) const {
    return s.length_m > 0.0f && (s.part == kNoPart || hit_parts_[s.part].hits == 0);
  }
  /// Bytes of the session records and their coverages; of the coarse entries, spans and marks.
  size_t sessionBytes() const;
  size_t coarseBytes() const;
  /// Re-lays the hit parts out for the list records `lists` (see relayout()).
  void packHitParts(std::vector<List>& lists);
  /// The entries of `l`, decoded into `scratch`.
  std::span<const Entry> decoded(const List& l, std::vector<Entry>& scratch) const;
  /// The depth-first copy of the tree `tree` that snapshot() and snapshotOfStates() make into
  /// `out`'s pools: `coarse(r)` gives the length of the one free leaf an inner node reads as at
  /// that time (std::optional<float>, none: descend), `list(r, v)` whether a list holds a value valid
  /// then, written to v. A node is reserved before its children and dropped again when
  /// none of them holds anything (it is then the last node in the pool). Counts into `seen`.
  template <class CoarseFn, class ListFn>
  static void copyTree(const std::vector<Children>& tree, CoarseFn&& coarse, ListFn&& list, size_t reserve_inner,
                       size_t reserve_leaves, SessionMap& out, SnapshotVisits& seen);
  static bool isList(Ref r) { return r != kEmpty && (r & kListBit) != 0; }
  static bool isInner(Ref r) { return r != kEmpty && (r & kListBit) == 0; }
  static uint32_t index(Ref r) { return r & ~kListBit; }

  const Stored* entriesOf(const List& l) const { return l.size == 1 ? &l.first : arena_.data() + l.block; }
  Stored* entriesOf(List& l) { return l.size == 1 ? &l.first : arena_.data() + l.block; }
  uint32_t newInner();
  uint32_t newList(const Stored& e);
  void freeList(uint32_t list);
  uint32_t allocBlock(int capacity_log2);
  void freeBlock(uint32_t block, int capacity_log2);
  void insertEntry(uint32_t list, size_t pos, const Stored& e);
  void eraseEntry(uint32_t list, size_t pos);
  /// Index of the first entry whose session is >= `session` (the insertion position).
  size_t lowerBound(const List& l, uint32_t session) const;
  /// Replaces the list in `slot` of `node` by an inner node with 8 lists that copy its
  /// history, counters split evenly. Returns the new inner node.
  uint32_t refine(uint32_t node, int slot);
  /// The first session after `rank` whose coverage meets the cube, and how.
  std::optional<std::pair<uint32_t, CoverageIndex::Overlap>> nextObserver(uint32_t rank, const VoxelKey& corner,
                                                                          int level);
  /// Applies the observation `value` of the cube (`corner`, `target_level`) by session `rank`,
  /// descending from inner node `node` at `level`.
  void apply(uint32_t node, int level, const VoxelKey& corner, int target_level, const VoxelCounters& value,
             uint32_t rank, AddReport& report);
  /// Records the observation in the list in `slot` of `node` (cube at `level`).
  void applyToList(uint32_t node, int slot, int level, const VoxelKey& corner, const VoxelCounters& value,
                   uint32_t rank, AddReport& report);
  /// Removes session `rank`'s entries below inner node `node`.
  void removeBelow(uint32_t node, int level, const VoxelKey& base, uint32_t rank);
  void removeFromList(uint32_t node, int slot, int level, const VoxelKey& corner, uint32_t rank);
  /// Adds `delta` to every entry's session number that is >= `from`.
  void shiftSessions(uint32_t from, int delta);
  bool compactBelow(Ref& r, int level);

  // Coarse entries (the versioned inner slots): per inner node, the rank intervals [from, to)
  // in which every voxel of its cube reads free without hits, with the cube's summed length as
  // compressFree() would sum it. Derived from the lists (never stored in files), kept up to date
  // at the end of every add, remove and read: nodes touched are marked and recomputed bottom up.
  struct Coarse {
    uint32_t from = 0, to = 0;  // ranks; to == kForever: still valid
    float length_m = 0.0f;
  };
  static constexpr uint32_t kForever = 0xffffffffu;
  struct CoarseSpan {
    uint32_t begin = 0, count = 0;
    Coarse newest;  // a copy of the last interval (count > 0): a snapshot of a late time reads
                    // it here, next to the span, instead of in the arena
  };
  std::vector<Coarse> coarse_;            // arena; spans of rebuilt nodes leave garbage behind
  std::vector<CoarseSpan> coarse_span_;   // per inner node
  std::vector<uint8_t> coarse_dirty_;     // per inner node: recompute its span
  size_t coarse_garbage_ = 0;
  std::vector<Coarse> coarse_scratch_;
  std::vector<uint32_t> path_;  // inner nodes from the root to where apply() is, while it runs
  /// Marks the nodes of path_ for recomputation (called where apply() changes something).
  void markPath();
  void markAllCoarseDirty();
  void updateCoarse();
  void rebuildCoarse(uint32_t node);
  /// Copies the live spans into a fresh arena in node order (drops the garbage).
  void packCoarse();
  /// The coarse entry of inner node `node` valid at rank `rank`, if any.
  const Coarse* coarseAt(uint32_t node, uint32_t rank) const {
    const CoarseSpan& span = coarse_span_[node];
    if (span.count == 0 || rank >= span.newest.to) return nullptr;
    if (rank >= span.newest.from) return &span.newest;
    return coarseBefore(span, rank);
  }
  const Coarse* coarseBefore(const CoarseSpan& span, uint32_t rank) const;

  // The layout of the pools (parts(), relayout()): old inner node and list indices in their new
  // order, and how many of each the latest snapshot reads (they come first).
  struct Layout {
    std::vector<uint32_t> inner, lists;
    size_t hot_inner = 0, hot_lists = 0;
  };
  Layout layout() const;
  /// Re-lays the pools out when scatteredHot() reaches a share of the block.
  void relayoutIfScattered();
  /// How many nodes the latest snapshot reads outside the block where the last layout put
  /// its nodes (created since, or no longer shadowed), and how many it reads in all.
  std::pair<size_t, Layout> scatteredHot() const;
  size_t hot_inner_at_layout_ = 0, hot_lists_at_layout_ = 0;  // the block: the first of each pool
  size_t relayouts_ = 0;
  bool compact_ = false;  // see isCompact()

  KeyGrid grid_;
  ChangeCriterion criterion_;
  std::vector<SessionRecord> sessions_;  // in time order; entries refer to these ranks
  std::vector<Children> inner_;          // inner_[0] is the root
  std::vector<List> lists_;
  std::vector<Stored> arena_;
  std::vector<HitPart> hit_parts_;
  std::vector<uint32_t> free_hit_parts_;
  std::vector<uint32_t> free_lists_;
  std::array<std::vector<uint32_t>, 17> free_blocks_;
  size_t live_lists_ = 0;
  size_t live_entries_ = 0;
  // Per inner node: bit (rank % 64) set when a change of that rank lies below (see
  // forEachListChangedIn); rebuilt on demand after any modification.
  mutable std::vector<uint64_t> change_masks_;
  mutable bool change_masks_valid_ = false;
  void buildChangeMasks() const;
  // Decoded coverages of sessions, filled on demand while one add or remove runs.
  std::vector<std::shared_ptr<const CoverageIndex>> coverage_cache_;
};

template <class Fn>
void TemporalMap::forEachList(Fn&& fn) const {
  std::vector<Entry> scratch;
  walkPoolTree(
      inner_, kListBit, [](uint32_t) { return true; },
      [&](Ref r, const VoxelKey& k, int level) { fn(k, level, decoded(lists_[index(r)], scratch)); });
}

template <class Fn>
void TemporalMap::forEachListPlace(Fn&& fn) const {
  walkPoolTree(
      inner_, kListBit, [](uint32_t) { return true; }, [&](Ref, const VoxelKey& k, int level) { fn(k, level); });
}

template <class Fn>
size_t TemporalMap::forEachListChangedIn(uint32_t first, uint32_t end, Fn&& fn) const {
  if (first >= end) return 0;
  if (!change_masks_valid_) buildChangeMasks();
  uint64_t query = ~uint64_t{0};
  if (end - first < 64) {
    query = 0;
    for (uint32_t r = first; r < end; ++r) query |= uint64_t{1} << (r % 64);
  }
  std::vector<Entry> scratch;
  return walkPoolTree(
      inner_, kListBit, [&](uint32_t node) { return (change_masks_[node] & query) != 0; },
      [&](Ref r, const VoxelKey& k, int level) {
        const List& l = lists_[index(r)];
        const Stored* entries = entriesOf(l);
        for (size_t i = 1; i < l.size; ++i) {
          if (entries[i].session >= first && entries[i].session < end) {
            fn(k, level, decoded(l, scratch));
            return;
          }
        }
      });
}

template <class Fn>
void TemporalMap::forEachChangeCount(double t0_s, double t1_s, Fn&& fn) const {
  // Ranks whose time lies in (t0, t1].
  const uint32_t first = ranksThrough(t0_s), end = ranksThrough(t1_s);
  if (first >= end) return;
  forEachListChangedIn(first, end, [&](const VoxelKey& k, int level, std::span<const Entry> entries) {
    uint32_t n = 0;
    for (size_t i = 1; i < entries.size(); ++i) {
      if (entries[i].session >= first && entries[i].session < end) ++n;
    }
    if (n > 0) fn(k, level, n);
  });
}

}  // namespace chronomap
