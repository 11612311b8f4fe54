#pragma once
/// @file
/// A window of a 4D map's history: what a snapshot at any time inside a run of sessions needs,
/// without the entries before or after it (issue 46: an older time of a tile read without its
/// whole history; docs/file-format.md, "Window files").

#include <cstdint>

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

}  // namespace chronomap
