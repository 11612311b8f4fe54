#include "chronomap/analysis/fitted_on.h"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"

namespace chronomap {

namespace {

/// FNV-1a, 64 bits, fed numbers as their little-endian bytes (the same on every machine).
class Fnv1a {
 public:
  void add(uint64_t value) {
    for (int i = 0; i < 8; ++i) {
      hash_ ^= (value >> (8 * i)) & 0xffu;
      hash_ *= 1099511628211ull;
    }
  }
  void add(double value) {
    uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof(bits));
    add(bits);
  }
  uint64_t value() const { return hash_ == 0 ? 1 : hash_; }

 private:
  uint64_t hash_ = 14695981039346656037ull;
};

std::string hex(uint64_t value) {
  char buf[24];
  std::snprintf(buf, sizeof(buf), "%016" PRIx64, value);
  return buf;
}

/// What a saved model says it was fitted on.
struct ModelFacts {
  const char* kind;  ///< "rhythm model", "colour model"
  double resolution_m, from_s, to_s;
  uint64_t sessions;
  const FittedOn& on;
};

/// The map's facts for messages: "b.cmap has 3 sessions from A to B".
std::string mapFacts(const TemporalMap& map, const std::string& name) {
  std::string out = name + " has " + countOf(map.sessionCount(), "session");
  if (map.sessionCount() > 0) {
    out += " from " + formatTime(map.sessions().front().time_s) + " to " + formatTime(map.sessions().back().time_s);
  }
  return out;
}

/// The learning sessions the model names: all of them when recorded, else its first and last.
std::vector<double> namedTimes(const ModelFacts& m) {
  if (m.on.recorded()) return m.on.times_s;
  if (m.sessions == 0) return {};
  if (m.from_s == m.to_s) return {m.from_s};
  return {m.from_s, m.to_s};
}

/// Why `map` is not the model's map ("" when it is, as far as the model tells).
std::string mismatch(const ModelFacts& m, const TemporalMap& map, const std::string& map_name) {
  const std::vector<double> times = namedTimes(m);
  const std::vector<double> have = map.times();
  std::vector<double> missing;
  for (double t : times) {
    if (!std::binary_search(have.begin(), have.end(), t)) missing.push_back(t);
  }
  if (!missing.empty()) {
    std::string why = map_name + " has no session at " + formatTime(missing.front());
    if (missing.size() > 1) why += " (nor at " + countOf(missing.size() - 1, "other") + " of them)";
    return why;
  }
  if (!m.on.recorded()) return "";
  const uint64_t there = mapFingerprint(map, times).value();
  if (there == m.on.fingerprint) return "";
  return "the sessions of " + map_name + " at those times observed other voxels (fingerprint " + hex(there) + ")";
}

std::string check(const ModelFacts& m, const TemporalMap& map, const FittedOnCheck& c) {
  if (!sameResolution(m.resolution_m, map.resolution_m())) {
    throw UsageError(c.model_name + ": the " + m.kind + " was fitted on a map of " + exactNumber(m.resolution_m) +
                     " m voxels, " + c.map_name + " has " + exactNumber(map.resolution_m()) + " m voxels; " +
                     c.refit);
  }
  const std::string why = mismatch(m, map, c.map_name);
  if (why.empty()) {
    if (m.on.recorded()) return "";
    return c.model_name + ": the " + m.kind +
           " records no fingerprint of the map it was fitted on (saved by an older chronomap, or fitted without "
           "a map), so it is checked against " + c.map_name +
           " only by its resolution and its first and last learning sessions; save it again to have it checked in full";
  }
  std::string text = c.model_name + ": the " + m.kind + " was fitted on another map: it learned from " +
                     countOf(m.sessions, "session") + " from " + formatTime(m.from_s) + " to " + formatTime(m.to_s);
  if (m.on.recorded()) text += " (map fingerprint " + hex(m.on.fingerprint) + ")";
  text += ", and " + why + "; " + mapFacts(map, c.map_name);
  if (c.allow_other_map) return text + "; used anyway, as " + (c.allow_flag.empty() ? "asked" : c.allow_flag + " asks");
  text += "; " + c.refit;
  if (!c.allow_flag.empty()) text += ", or pass " + c.allow_flag + " to use it anyway";
  throw UsageError(text);
}

}  // namespace

std::optional<uint64_t> mapFingerprint(const TemporalMap& map, std::span<const double> times_s) {
  const std::vector<double> have = map.times();
  Fnv1a h;
  h.add(map.resolution_m());
  h.add(static_cast<uint64_t>(times_s.size()));
  for (double t : times_s) {
    const auto it = std::lower_bound(have.begin(), have.end(), t);
    if (it == have.end() || *it != t) return std::nullopt;
    h.add(t);
    // The runs of observed Morton codes, adjacent runs joined: the same set reads the same
    // however its ranges were cut (a tiled map joined again).
    const std::vector<uint64_t> ranges = map.sessions()[static_cast<size_t>(it - have.begin())].coverage.ranges();
    for (size_t i = 0; i + 1 < ranges.size(); i += 2) {
      const uint64_t begin = ranges[i];
      uint64_t end = ranges[i + 1];
      while (i + 3 < ranges.size() && ranges[i + 2] == end) {
        end = ranges[i + 3];
        i += 2;
      }
      h.add(begin);
      h.add(end);
    }
    h.add(~uint64_t{0});  // the end of this session's runs
  }
  return h.value();
}

FittedOn fittedOn(const TemporalMap& map, double from_s, double to_s) {
  FittedOn on;
  for (double t : map.times()) {
    if (t >= from_s && t <= to_s) on.times_s.push_back(t);
  }
  on.fingerprint = mapFingerprint(map, on.times_s).value();
  return on;
}

bool sameResolution(double a_m, double b_m) { return std::abs(a_m - b_m) <= 1e-9 * std::max(std::abs(a_m), std::abs(b_m)); }

std::string checkFittedOn(const RhythmModels& models, const TemporalMap& map, const FittedOnCheck& c) {
  return check({"rhythm model", models.resolution_m, models.from_s, models.to_s, models.sessions, models.fitted_on},
               map, c);
}

std::string checkFittedOn(const ColourModel& model, const TemporalMap& map, const FittedOnCheck& c) {
  return check({"colour model", model.resolution_m, model.from_s, model.to_s, model.sessions, model.fitted_on}, map,
               c);
}

}  // namespace chronomap
