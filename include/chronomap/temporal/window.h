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

/// A window that goes on after `map`'s last session (docs/scale.md, "A tile as its windows"):
/// `map`'s tree, each list holding its latest entry as the window's session 0, which stands for
/// `map`'s last session (its time and name, no coverage): historyWindow(map, last, 1). Sessions
/// added after it are the window's own; each decides its changes against the latest states as
/// `map` would. Compacting the window with compact(relayout, &kept), `kept` its parts().inner
/// as returned here, merges exactly what compacting the whole history would.
/// @throw UsageError when `map` holds no session.
TemporalMap continuedWindow(const TemporalMap& map);

/// `map`'s history cut into windows of `k` sessions as joinWindows joins them: window 0 holds
/// sessions [0, k), window j > 0 continues window j - 1 (its session 0 carrying the states of
/// session j·k - 1) and holds sessions [j·k, (j + 1)·k); the last may hold fewer. Each has
/// `map`'s tree without the lists first observed after its last session (and the inner nodes
/// left without children), so that joinWindows gives `map` back bit for bit, and its snapshot at
/// any of its sessions is `map`'s, node for node. The sessions keep their records (coverage
/// included) but for the carried session 0, whose coverage is left out. To go on adding
/// sessions to the last window, compact it with the window before it's tree as the kept tree
/// (compact(relayout, &kept)), or with none when it is the only one.
/// @throw UsageError when k is 0 or `map` holds no session.
std::vector<TemporalMap> windowsOf(const TemporalMap& map, uint32_t k);

/// The whole history that a run of windows holds: windows[0] from the first session, and each
/// later window continued from the one before it (continuedWindow) and added to and compacted
/// as above. The result is the map that adding the same sessions to one map, compacting it after
/// each, would give: the same tree, lists, entries and lengths, bit for bit. The last window's
/// tree is the map's; a list that an earlier window held coarser (a refinement came later) takes
/// that window's entries split as a refinement splits them, and a cube that it held finer (a
/// merge came later) the merge of its lists, summed as compaction sums them. The sessions are
/// the windows' own (session 0 of a continued window left out), node counts as each window
/// counted them.
/// @throw UsageError when there is no window, they differ in resolution or criterion, or a
/// window's session 0 is not the time of the last session before it; FormatError when their
/// trees do not join (a merge of lists that are not free on the same sessions, or a list with
/// no entry).
TemporalMap joinWindows(const std::vector<TemporalMap>& windows);

}  // namespace chronomap
