#pragma once
/// @file
/// A window of a 4D map's history: what a snapshot at any time inside a run of sessions needs,
/// without the entries before or after it (issue 46: an older time of a tile read without its
/// whole history; docs/file-format.md, "Window files").

#include <cstdint>
#include <vector>

#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// The window of `map` over its sessions of rank [first, first + count): a 4D map whose first
/// session is `map`'s session `first`, holding `map`'s tree and, in each list, the entry valid
/// at session `first` (moved to the window's first session) and the entries of the window's
/// sessions. A list first observed after the window keeps its first entry only, and the
/// window then also holds the sessions up to the latest such entry (its sessions are `map`'s
/// [first, first + window.sessionCount())). The sessions keep their times, names and node
/// counts; their coverage is left out.
///
/// Its snapshot at any time from session `first`'s to session first + count - 1's is the
/// snapshot of `map` at that time, node for node (the tree is `map`'s: the snapshot reads the
/// same entries in the same order). Times after it answer nothing useful.
/// @throw UsageError when count is 0 or the window does not lie inside the map's sessions.
TemporalMap historyWindow(const TemporalMap& map, uint32_t first, uint32_t count);
/// The same from `parts`, map.parts(): for several windows of one map, which parts() would
/// otherwise copy whole for each.
TemporalMap historyWindow(const TemporalMap& map, const TemporalMap::Parts& parts, uint32_t first, uint32_t count);

/// `map`'s history cut into windows of `k` sessions as joinWindows joins them: window 0 holds
/// sessions [0, f) with f = `first_k` (0: k; any f > 0, one window when f is the session count
/// or more), window j > 0 continues window j - 1 (its session 0 carrying the states of session
/// f + (j - 1)·k - 1) and holds sessions [f + (j - 1)·k, f + j·k); the last may hold fewer.
/// Each has `map`'s tree without the lists first observed after its last session (and the inner
/// nodes left without children), so that joinWindows gives `map` back bit for bit, and its
/// snapshot at any of its sessions is `map`'s, node for node. The sessions keep their records
/// (coverage included) but for the carried session 0, whose coverage is left out.
/// @throw UsageError when k is 0 or `map` holds no session.
std::vector<TemporalMap> windowsOf(const TemporalMap& map, uint32_t k, uint32_t first_k = 0);

/// A window that goes on after `map`'s last session (docs/scale.md, "A tile as its windows"):
/// historyWindow(map, last, 1), each list holding its latest entry as the window's session 0
/// (which stands for `map`'s last session: its time and name, no coverage), then compacted: the
/// lists whose carried states are free without hits merge, so that the window's tree follows
/// what the place holds now rather than every refinement its history made. Sessions added after
/// it decide their changes as `map` would (a free state without hits never differs from another
/// one, whatever the lengths), and joinWindows gives back the map that adding them to `map`
/// would make.
/// @throw UsageError when `map` holds no session.
TemporalMap continuedWindow(const TemporalMap& map);

/// The whole history that a run of windows holds: windows[0] from the first session, each later
/// one continued from the one before it (continuedWindow, or windowsOf). When the one map and
/// the windows take the same sessions and are compacted at the same points (after every night
/// or run of sessions; a window closed and continued only at such a point), the result is the
/// one map: the same tree, lists and entries, bit for bit (the sessions' node counts are each
/// window's own). Its tree is the union of the windows' trees (the finest any of them holds at
/// each place); a list that a window holds coarser takes that window's entries split as
/// TemporalMap's refinement splits them; the state each continued window carries at its session
/// 0 is left out, once checked to be the state the windows before it end with (the same, or,
/// free without hits, of another length).
/// @throw UsageError when there is no window, they differ in resolution or criterion, or a
/// window's session 0 is not the time of the last session before it; FormatError when their
/// trees do not join: a carried state that is not the one before, a place observed before a
/// window that it lacks or carries nothing into, or one it carries a state into that no window
/// before it observed.
TemporalMap joinWindows(const std::vector<TemporalMap>& windows);

}  // namespace chronomap
