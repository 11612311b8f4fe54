// A saved model belongs to the map it was fitted on: what it records (the learning sessions'
// times and a fingerprint of the map over them), and checkFittedOn's answers for that map, the
// same map grown or saved, another map, another resolution and a model that records nothing.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "builders.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/fitted_on.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/temporal/tiles.h"
#include "test_support.h"

namespace chronomap {
namespace {

using test::at;

/// Sessions at 100, 200, ... s of a row of voxels where the voxel at `moving` is occupied in every
/// other session; `shift` moves the whole row (another map of the same sessions' times).
TemporalMap rowMap(int sessions, int shift = 0, double resolution_m = 0.05) {
  TemporalMap map(resolution_m);
  for (int i = 0; i < sessions; ++i) {
    SessionMap s(resolution_m);
    for (int x = 0; x < 6; ++x) {
      const bool occupied = x == 0 || (x == 3 && i % 2 == 0);
      s.add(at(x + shift, 0, 0), occupied ? test::occupiedVoxel(Rgb{200, 10, 10}) : test::freeVoxel());
    }
    map.add(100.0 * (i + 1), s);
  }
  return map;
}

/// The message checkFittedOn throws, or "accepted: " and its warning.
template <class Model>
std::string answer(const Model& model, const TemporalMap& map, bool allow = false) {
  const FittedOnCheck check{"a.rhythm", "b.cmap", "leave out --rhythm", "--allow-other-map", allow};
  try {
    return "accepted: " + checkFittedOn(model, map, check);
  } catch (const UsageError& e) {
    return e.what();
  }
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(FittedOn, AModelRecordsItsSessionsAndIsRefusedOnAnotherMap) {
  const TemporalMap a = rowMap(6);
  const RhythmModels models = fitRhythm(a, 200.0, 500.0);
  EXPECT_EQ(models.fitted_on.times_s, (std::vector<double>{200.0, 300.0, 400.0, 500.0}));
  EXPECT_EQ(models.fitted_on.fingerprint, mapFingerprint(a, models.fitted_on.times_s));
  EXPECT_NE(models.fitted_on.fingerprint, 0u);
  EXPECT_EQ(answer(models, a), "accepted: ");
  // The same map with a later session, and with an earlier one: the learning sessions are there.
  TemporalMap grown = rowMap(7);
  EXPECT_EQ(answer(models, grown), "accepted: ");
  grown.remove(100.0);
  EXPECT_EQ(answer(models, grown), "accepted: ");

  // Another map with the same sessions' times: the voxels they observed differ.
  const TemporalMap other = rowMap(6, 40);
  const std::string refused = answer(models, other);
  EXPECT_TRUE(has(refused, "a.rhythm: the rhythm model was fitted on another map")) << refused;
  EXPECT_TRUE(has(refused, "4 sessions from " + formatTime(200.0) + " to " + formatTime(500.0))) << refused;
  EXPECT_TRUE(has(refused, "observed other voxels")) << refused;
  EXPECT_TRUE(has(refused, "b.cmap has 6 sessions from " + formatTime(100.0) + " to " + formatTime(600.0))) << refused;
  EXPECT_TRUE(has(refused, "leave out --rhythm, or pass --allow-other-map to use it anyway")) << refused;
  // A map without those sessions: the first one missing is named.
  const TemporalMap short_map = rowMap(3);
  const std::string missing = answer(models, short_map);
  EXPECT_TRUE(has(missing, "b.cmap has no session at " + formatTime(400.0) + " (nor at 1 other of them)")) << missing;
  EXPECT_TRUE(has(missing, "b.cmap has 3 sessions")) << missing;
  // Allowed: the same facts as a warning.
  const std::string allowed = answer(models, other, true);
  EXPECT_TRUE(has(allowed, "accepted: a.rhythm: the rhythm model was fitted on another map")) << allowed;
  EXPECT_TRUE(has(allowed, "used anyway, as --allow-other-map asks")) << allowed;

  // A colour model is checked the same way.
  ColourModel colour;
  colour.resolution_m = a.resolution_m();
  colour.from_s = 200.0;
  colour.to_s = 500.0;
  colour.sessions = 4;
  colour.fitted_on = fittedOn(a, 200.0, 500.0);
  EXPECT_EQ(answer(colour, a), "accepted: ");
  EXPECT_TRUE(has(answer(colour, other), "a.rhythm: the colour model was fitted on another map")) << answer(colour, other);
}

TEST(FittedOn, TheFingerprintSurvivesSavingCompactingAndTiling) {
  test::TempDir tmp;
  const TemporalMap a = rowMap(5);
  const std::vector<double> times = a.times();
  const uint64_t fingerprint = *mapFingerprint(a, times);
  writeTemporalMap(tmp / "a.cmap", a, {});
  EXPECT_EQ(mapFingerprint(readTemporalMap(tmp / "a.cmap"), times), fingerprint);
  TemporalMap compacted = a;
  compacted.compact();
  EXPECT_EQ(mapFingerprint(compacted, times), fingerprint);
  const SplitMap split = splitIntoTiles(a, 1);
  std::vector<const Tile*> tiles;
  for (const Tile& t : split.tiles) tiles.push_back(&t);
  EXPECT_EQ(mapFingerprint(joinTiles(split.top, 1, tiles), times), fingerprint);
  // Other sessions, another place, another resolution: another fingerprint; a time the map lacks: none.
  EXPECT_NE(mapFingerprint(a, std::vector<double>(times.begin(), times.end() - 1)), fingerprint);
  EXPECT_NE(mapFingerprint(rowMap(5, 1), times), fingerprint);
  EXPECT_NE(mapFingerprint(rowMap(5, 0, 0.1), times), fingerprint);
  EXPECT_EQ(mapFingerprint(a, std::vector<double>{150.0}), std::nullopt);
}

TEST(FittedOn, ResolutionsThatDifferAreRefusedWithDigitsThatShowIt) {
  const TemporalMap a = rowMap(4);
  const TemporalMap finer = rowMap(4, 0, 0.05 * (1.0 + 1e-7));
  const RhythmModels models = fitRhythm(a, 0.0, 1000.0);
  const std::string refused = answer(models, finer);
  EXPECT_TRUE(has(refused, "fitted on a map of 0.05 m voxels, b.cmap has " + exactNumber(finer.resolution_m()) +
                               " m voxels; leave out --rhythm"))
      << refused;
  EXPECT_NE(exactNumber(finer.resolution_m()), "0.05");
  // Not even --allow-other-map uses a model of other keys; predictMap says the same.
  EXPECT_FALSE(has(answer(models, finer, true), "accepted"));
  try {
    predictMap(finer, models, RhythmModel::Mean, 500.0);
    ADD_FAILURE();
  } catch (const UsageError& e) {
    EXPECT_TRUE(has(e.what(), "fitted at 0.05 m, the map has " + exactNumber(finer.resolution_m()) + " m")) << e.what();
  }
  // Within a relative 1e-9 the keys are the same: accepted.
  EXPECT_TRUE(sameResolution(0.05, 0.05 * (1.0 + 1e-10)));
  EXPECT_FALSE(sameResolution(0.05, 0.05 * (1.0 + 1e-8)));
}

TEST(FittedOn, AModelWithoutAFingerprintIsCheckedByItsRangeWithAWarning) {
  const TemporalMap a = rowMap(6);
  RhythmModels old = fitRhythm(a, 200.0, 500.0);
  old.fitted_on = {};  // as read from a version 3 file
  const std::string warned = answer(old, a);
  EXPECT_TRUE(has(warned, "accepted: a.rhythm: the rhythm model records no fingerprint")) << warned;
  EXPECT_TRUE(has(warned, "checked against b.cmap only by its resolution and its first and last learning sessions"))
      << warned;
  // Its first or last learning session missing from the map: refused all the same.
  const std::string refused = answer(old, rowMap(4));
  EXPECT_TRUE(has(refused, "b.cmap has no session at " + formatTime(500.0))) << refused;
  EXPECT_FALSE(has(refused, "accepted")) << refused;
  // Another map with the same times cannot be told apart: the warning says so.
  EXPECT_TRUE(has(answer(old, rowMap(6, 40)), "accepted: a.rhythm: the rhythm model records no fingerprint"));
}

}  // namespace
}  // namespace chronomap
