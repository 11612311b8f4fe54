#pragma once
/// @file
/// What a saved model was fitted on (analysis/fitted_on.h), as .rhythm (version 4) and .colour
/// (version 2) store it after their headers: the map's fingerprint (u64, 0: not recorded), the
/// number of learning sessions' times (u64: 0, or the header's session count), then the times
/// (f64 each, increasing, the first and last the header's learning range). Internal to
/// chronomap_store.

#include <cstdint>
#include <string>

#include "chronomap/analysis/fitted_on.h"
#include "chronomap/core/byte_buffer.h"

namespace chronomap {

/// Appends `on`.
void putFittedOn(ByteWriter& w, const FittedOn& on);

/// The header's learning range, which the times must agree with.
struct LearnedRange {
  uint64_t sessions = 0;
  double from_s = 0.0, to_s = 0.0;
};

/// Reads what putFittedOn wrote, checking it against `range` and refusing a count of times that
/// the bytes left cannot hold before anything is allocated.
/// @throw FormatError naming `r.source`.
FittedOn getFittedOn(ByteReader& r, const LearnedRange& range);

/// Refuses learning times that are not finite or run backwards (every version's header).
/// @throw FormatError naming `source`.
void checkLearnedRange(const LearnedRange& range, const std::string& source);

}  // namespace chronomap
