#include "fitted_on_record.h"

#include <cmath>

#include "chronomap/core/error.h"

namespace chronomap {

void putFittedOn(ByteWriter& w, const FittedOn& on) {
  w.put(on.fingerprint);
  w.put(static_cast<uint64_t>(on.recorded() ? on.times_s.size() : 0));
  if (!on.recorded()) return;
  for (double t : on.times_s) w.put(t);
}

void checkLearnedRange(const LearnedRange& range, const std::string& source) {
  if (!std::isfinite(range.from_s) || !std::isfinite(range.to_s) || range.to_s < range.from_s) {
    throw FormatError(source + ": bad header (the learning sessions' first and last times are not a range of times)");
  }
}

FittedOn getFittedOn(ByteReader& r, const LearnedRange& range) {
  FittedOn on;
  on.fingerprint = r.get<uint64_t>();
  const auto count = r.get<uint64_t>();
  if ((count == 0) != (on.fingerprint == 0)) {
    throw FormatError(r.source + ": bad header (a map fingerprint " + (count == 0 ? "without" : "missing for") +
                      " the learning sessions' times)");
  }
  if (count == 0) return on;
  if (count != range.sessions) {
    throw FormatError(r.source + ": bad header (" + std::to_string(range.sessions) + " learning sessions but " +
                      std::to_string(count) + " times)");
  }
  if (count > (r.bytes.size() - r.pos) / sizeof(double)) {
    throw FormatError(r.source + ": the header announces " + std::to_string(count) +
                      " learning sessions' times, more than the " + std::to_string(r.bytes.size() - r.pos) +
                      " bytes left hold (truncated or corrupt)");
  }
  on.times_s.resize(count);
  for (size_t i = 0; i < count; ++i) {
    on.times_s[i] = r.get<double>();
    if (!std::isfinite(on.times_s[i]) || (i > 0 && !(on.times_s[i] > on.times_s[i - 1]))) {
      throw FormatError(r.source + ": the learning sessions' times are not finite and increasing");
    }
  }
  if (on.times_s.front() != range.from_s || on.times_s.back() != range.to_s) {
    throw FormatError(r.source + ": the learning sessions' times do not run from the header's first to its last");
  }
  return on;
}

}  // namespace chronomap
