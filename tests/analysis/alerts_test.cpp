// Which changes are unusual (analysis/alerts.h): analytic histories with known answers, the
// neighbourhood, reasons naming the evidence, bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "builders.h"
#include "chronomap/analysis/alerts.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"

namespace chronomap {
namespace {

using test::at;
using test::freeVoxel;
using test::occupiedVoxel;

using test::kHour;
using test::kMonday_s;

double when(int day, double hour) { return kMonday_s + 86400.0 * day + kHour * hour; }

/// A 3 x 3 x 3 object (27 voxels) with its lower corner at (x, y, 1).
struct Cube {
  int x = 0, y = 0;
  Rgb colour{200, 40, 40};
  bool contains(int vx, int vy, int vz) const { return vx >= x && vx < x + 3 && vy >= y && vy < y + 3 && vz >= 1 && vz < 4; }
};

/// A session observing the block 0..23 x 0..11 x 0..5, every voxel free but the given cubes'.
SessionMap sessionWith(const std::vector<Cube>& cubes) {
  SessionMap s(0.05);
  for (int z = 0; z < 6; ++z) {
    for (int y = 0; y < 12; ++y) {
      for (int x = 0; x < 24; ++x) {
        const Cube* in = nullptr;
        for (const Cube& c : cubes) {
          if (c.contains(x, y, z)) in = &c;
        }
        s.add(at(x, y, z), in ? occupiedVoxel(in->colour) : freeVoxel());
      }
    }
  }
  return s;
}

/// Plain hard diffs: the test maps have no localisation error to forgive.
AlertSettings plain() {
  AlertSettings s;
  s.diff = DiffSettings{};
  return s;
}

TEST(Alerts, SpaceFreeInEveryObservationThenOccupiedScoresHigh) {
  TemporalMap map(0.05);
  for (int d = 0; d < 20; ++d) {
    map.add(when(d, 9.0), sessionWith({}));
    map.add(when(d, 21.0), sessionWith({}));
  }
  map.add(when(20, 9.0), sessionWith({}));  // 41 observations
  map.add(when(20, 15.0), sessionWith({{10, 4}}));
  const AlertReport r = findAlerts(map, when(20, 15.0), plain());
  ASSERT_EQ(r.alerts.size(), 1u);
  const Alert& a = r.alerts[0];
  EXPECT_EQ(a.component.kind, ChangeKind::Appeared);
  EXPECT_EQ(a.component.voxels, 27u);
  EXPECT_EQ(r.history_sessions, 41u);
  EXPECT_EQ(a.evidence.observations, 41u);
  EXPECT_EQ(a.evidence.in_state, 0u);
  // Day 20 is a Sunday and nothing was observed near 15:00: the all-hours share
  // (0 + 0.5) / (41 + 1) is all the probability there is.
  const double expected = 0.5 / 42.0;
  EXPECT_NEAR(a.probability, expected, 1e-9);
  EXPECT_NEAR(a.score_bits, -std::log2(expected), 1e-9);
  EXPECT_GT(a.score_bits, 6.0);
  EXPECT_EQ(a.reason, "this space was free in all 41 earlier observations") << a.reason;
  EXPECT_DOUBLE_EQ(r.previous_time_s, when(20, 9.0));
}

TEST(Alerts, SpaceThatFlipsEveryDayAtThatHourScoresLow) {
  // Occupied at 10:00 every day, free at 22:00: at 10:00 on day 21 its appearance is routine.
  TemporalMap map(0.05);
  for (int d = 0; d < 21; ++d) {
    map.add(when(d, 10.0), sessionWith({{10, 4}}));
    map.add(when(d, 22.0), sessionWith({}));
  }
  map.add(when(21, 10.0), sessionWith({{10, 4}}));
  const AlertReport r = findAlerts(map, when(21, 10.0), plain());
  ASSERT_EQ(r.alerts.size(), 1u);
  const Alert& a = r.alerts[0];
  EXPECT_LT(a.score_bits, 0.3);
  EXPECT_EQ(a.neighbour_distance_voxels, 0);
  // Day 21 is a Monday: the 15 weekdays' 10:00 observations are the window.
  EXPECT_EQ(a.evidence.window_observations, 15u);
  EXPECT_EQ(a.evidence.window_in_state, 15u);
  EXPECT_EQ(a.reason,
            "this space is usually occupied at 10:00: occupied in 15 of 15 earlier observations within 1.5 h of it on "
            "weekdays (occupied in 21 of 42 at any time)")
      << a.reason;
  // The same space vanishing at 10:00 instead would be unusual: it always stood there then.
  TemporalMap gone = map;
  gone.add(when(21, 11.0), sessionWith({}));
  const AlertReport g = findAlerts(gone, when(21, 11.0), plain());
  ASSERT_EQ(g.alerts.size(), 1u);
  EXPECT_EQ(g.alerts[0].component.kind, ChangeKind::Vanished);
  // The window of 11:00 on a weekday: 16 weekdays' 10:00 observations (weight 1; day 21's too)
  // and 6 weekend ones (0.25), none free; free in 21 of 43 at any time.
  const double p_all = 21.5 / 44.0;
  EXPECT_NEAR(g.alerts[0].probability, 3.0 * p_all / (16.0 + 1.5 + 3.0), 1e-12);
  EXPECT_GT(g.alerts[0].score_bits, 3.5);
  EXPECT_NE(g.alerts[0].reason.find("usually occupied at 11:00"), std::string::npos) << g.alerts[0].reason;
}

TEST(Alerts, DoorOpenAtThreeIsUnusualWhereItIsOpenByDay) {
  // A "door" (the cube) closed at night and open (absent) by day; open at 03:00 on day 14.
  TemporalMap map(0.05);
  for (int d = 0; d < 14; ++d) {
    map.add(when(d, 3.0), sessionWith({{4, 4}}));
    map.add(when(d, 13.0), sessionWith({}));
  }
  map.add(when(14, 0.5), sessionWith({{4, 4}}));
  map.add(when(14, 3.0), sessionWith({}));
  const AlertReport r = findAlerts(map, when(14, 3.0), plain());
  ASSERT_EQ(r.alerts.size(), 1u);
  EXPECT_EQ(r.alerts[0].component.kind, ChangeKind::Vanished);
  EXPECT_GT(r.alerts[0].score_bits, 3.0);
  EXPECT_NE(r.alerts[0].reason.find("this space is usually occupied at 03:00: occupied in 10 of 10"), std::string::npos)
      << r.alerts[0].reason;
  // By day the same change is ordinary.
  TemporalMap day = map;
  day.remove(when(14, 3.0));
  day.add(when(14, 13.0), sessionWith({}));
  EXPECT_LT(findAlerts(day, when(14, 13.0), plain()).alerts[0].score_bits, 0.5);
}

TEST(Alerts, TheNeighbourhoodMakesAnObjectMovedNearItsUsualPlaceRoutine) {
  // A chair at a slightly different place every day at 10:00 (x 4..6), gone at 22:00. On day 14
  // it stands two voxels beyond any earlier place (x 8: voxels x 10 never held it) - routine, its
  // neighbours held it at this hour; at x 18, far from them, it is not.
  TemporalMap map(0.05);
  for (int d = 0; d < 14; ++d) {
    map.add(when(d, 10.0), sessionWith({{4 + d % 3, 4}}));
    map.add(when(d, 22.0), sessionWith({}));
  }
  TemporalMap near = map, far = map;
  near.add(when(14, 10.0), sessionWith({{8, 4}}));
  far.add(when(14, 10.0), sessionWith({{18, 4}}));
  const AlertReport n = findAlerts(near, when(14, 10.0), plain());
  const AlertReport f = findAlerts(far, when(14, 10.0), plain());
  ASSERT_EQ(n.alerts.size(), 1u);
  ASSERT_EQ(f.alerts.size(), 1u);
  // Near: the copy shifted by one voxel (x 7..9) was free at 10:00 when the chair stood at x 4,
  // occupied when at x 6, and partly occupied (no evidence) when at x 5: likely, about 0.4.
  EXPECT_LT(n.alerts[0].score_bits, 1.5);
  EXPECT_GT(f.alerts[0].score_bits, 4.0);
  EXPECT_GT(f.alerts[0].score_bits, n.alerts[0].score_bits + 3.0);
  EXPECT_EQ(f.alerts[0].reason, "this space was free in all 28 earlier observations") << f.alerts[0].reason;
  // Without the neighbourhood, the voxels of the near chair that never held it make it unusual.
  AlertSettings alone = plain();
  alone.neighbourhood_voxels = 0;
  EXPECT_GT(findAlerts(near, when(14, 10.0), alone).alerts[0].score_bits, 4.0);
}

TEST(Alerts, RareObjectsRankAboveRoutineOnesAndTheHistoryCanEndEarly) {
  // A cube that comes at 10:00 every day, and on day 14 a second one where nothing ever stood.
  TemporalMap map(0.05);
  for (int d = 0; d < 14; ++d) {
    map.add(when(d, 10.0), sessionWith({{4, 4}}));
    map.add(when(d, 22.0), sessionWith({}));
  }
  map.add(when(14, 10.0), sessionWith({{4, 4}, {16, 4}}));
  const AlertReport r = findAlerts(map, when(14, 10.0), plain());
  ASSERT_EQ(r.alerts.size(), 2u);
  EXPECT_GT(r.alerts[0].component.bbox_min_m.x(), r.alerts[1].component.bbox_max_m.x());
  EXPECT_GT(r.alerts[0].score_bits, r.alerts[1].score_bits + 3.0);
  // History up to day 7 only: 14 sessions of evidence.
  AlertSettings early = plain();
  early.history_to_s = when(7, 0.0);
  const AlertReport e = findAlerts(map, when(14, 10.0), early);
  EXPECT_EQ(e.history_sessions, 14u);
  EXPECT_EQ(e.alerts[0].reason, "this space was free in all 14 earlier observations");
}

TEST(Alerts, StateEvidenceWeighsTheHourAndFallsBackToAllHours) {
  // One observation at the same hour, in the state asked: window weight 1, all-hours share
  // (1 + 0.5) / 2, of strength 3.
  const StateEvidence one = stateEvidence({when(0, 10.0)}, {1}, true, when(7, 10.5));
  EXPECT_EQ(one.observations, 1u);
  EXPECT_EQ(one.window_observations, 1u);
  EXPECT_DOUBLE_EQ(one.all_hours_probability, 0.75);
  EXPECT_DOUBLE_EQ(one.probability, (1.0 + 3.0 * 0.75) / 4.0);
  // Nothing observed: the all-hours share alone, one half.
  EXPECT_DOUBLE_EQ(stateEvidence({}, {}, true, when(0, 3.0)).probability, 0.5);
  // Observations at other hours only: the all-hours share alone.
  const StateEvidence night = stateEvidence({when(0, 10.0), when(1, 10.0)}, {1, 1}, true, when(2, 3.0));
  EXPECT_EQ(night.window_observations, 0u);
  EXPECT_DOUBLE_EQ(night.probability, 2.5 / 3.0);
  // A weekend observation counts a quarter on a weekday.
  const StateEvidence weekend = stateEvidence({when(5, 10.0)}, {0}, true, when(7, 10.0));
  EXPECT_EQ(weekend.window_observations, 0u);
  EXPECT_DOUBLE_EQ(weekend.probability, (0.0 + 3.0 * 0.25) / (0.25 + 3.0));
}

TEST(Alerts, FewObservationsAtTheHourFallBackToTheAllHoursEvidence) {
  // A space free in 30 observations at 03:00 on weekdays. Seen occupied once at 15:00, that one
  // observation does not make it usually occupied at 15:00; seen so on 12 weekdays, it does.
  std::vector<double> times;
  std::vector<uint8_t> occupied;
  for (int d = 0; d < 42 && times.size() < 30; ++d) {
    if (d % 7 < 5) {
      times.push_back(when(d, 3.0));
      occupied.push_back(0);
    }
  }
  const double t = when(44, 15.0);  // a Wednesday
  auto withDaysAt15 = [&](int n) {
    std::vector<double> ts = times;
    std::vector<uint8_t> os = occupied;
    for (int d = 0; n > 0; ++d) {
      if (d % 7 < 5) {
        ts.push_back(when(d, 15.0));
        os.push_back(1);
        --n;
      }
    }
    return stateEvidence(ts, os, true, t);
  };
  const StateEvidence once = withDaysAt15(1);
  EXPECT_EQ(once.window_observations, 1u);
  EXPECT_DOUBLE_EQ(once.all_hours_probability, 1.5 / 32.0);
  EXPECT_DOUBLE_EQ(once.probability, (1.0 + 3.0 * 1.5 / 32.0) / 4.0);
  EXPECT_LT(once.probability, 0.5);
  const StateEvidence often = withDaysAt15(12);
  EXPECT_EQ(often.window_observations, 12u);
  EXPECT_DOUBLE_EQ(often.probability, (12.0 + 3.0 * 12.5 / 43.0) / 15.0);
  EXPECT_GT(often.probability, 0.8);
  // The strength of the all-hours evidence is a setting: weaker, the one observation counts more.
  EvidenceSettings weak;
  weak.all_hours_observations = 0.5;
  std::vector<double> ts = times;
  std::vector<uint8_t> os = occupied;
  ts.push_back(when(0, 15.0));
  os.push_back(1);
  EXPECT_DOUBLE_EQ(stateEvidence(ts, os, true, t, weak).probability, (1.0 + 0.5 * 1.5 / 32.0) / 1.5);
}

TEST(Alerts, AMovedObjectIsScoredAsOne) {
  // A chair at x 4 that leaves its place at lunch (12:00) every day and stands there at 09:00
  // and 22:00. On day 14 (a Monday) at 12:00 it leaves its place and appears at x 16, where
  // nothing ever stood: its vanished half is routine on its own, the move is not.
  TemporalMap map(0.05);
  for (int d = 0; d < 14; ++d) {
    map.add(when(d, 9.0), sessionWith({{4, 4}}));
    map.add(when(d, 12.0), sessionWith({}));
    map.add(when(d, 22.0), sessionWith({{4, 4}}));
  }
  map.add(when(14, 9.0), sessionWith({{4, 4}}));
  map.add(when(14, 12.0), sessionWith({{16, 4}}));
  AlertSettings alone = plain();
  alone.moves.pair = false;
  const AlertReport apart = findAlerts(map, when(14, 12.0), alone);
  ASSERT_EQ(apart.alerts.size(), 2u);
  EXPECT_EQ(apart.alerts[0].component.kind, ChangeKind::Appeared);
  EXPECT_GT(apart.alerts[0].score_bits, 6.0);
  EXPECT_LT(apart.alerts[1].score_bits, 0.5);  // free at 12:00 in every earlier observation
  EXPECT_EQ(apart.alerts[1].moved_with, 0u);

  const AlertReport r = findAlerts(map, when(14, 12.0), plain());
  ASSERT_EQ(r.alerts.size(), 2u);
  const Alert& come = r.alerts[0].component.kind == ChangeKind::Appeared ? r.alerts[0] : r.alerts[1];
  const Alert& gone = r.alerts[0].component.kind == ChangeKind::Appeared ? r.alerts[1] : r.alerts[0];
  EXPECT_EQ(come.moved_with, gone.component.id);
  EXPECT_EQ(gone.moved_with, come.component.id);
  // The move is at most as likely as its less likely half: both get the appeared half's score.
  EXPECT_DOUBLE_EQ(come.own_score_bits, apart.alerts[0].score_bits);
  EXPECT_DOUBLE_EQ(gone.own_score_bits, apart.alerts[1].score_bits);
  EXPECT_DOUBLE_EQ(gone.score_bits, come.own_score_bits);
  EXPECT_DOUBLE_EQ(come.score_bits, come.own_score_bits);
  EXPECT_DOUBLE_EQ(gone.probability, std::exp2(-come.own_score_bits));
  EXPECT_EQ(gone.reason.rfind("moved: it appeared 0.6 m away at (", 0), 0u) << gone.reason;
  EXPECT_NE(gone.reason.find("), where this space was free in all 43 earlier observations"), std::string::npos)
      << gone.reason;
  EXPECT_EQ(come.reason.rfind("moved from 0.6 m away at (", 0), 0u) << come.reason;
  EXPECT_NE(come.reason.find("): this space was free in all 43 earlier observations"), std::string::npos)
      << come.reason;

  // An object of another colour is no half of the move: a green box appearing instead.
  TemporalMap other = map;
  other.remove(when(14, 12.0));
  other.add(when(14, 12.0), sessionWith({{16, 4, Rgb{30, 200, 30}}}));
  const AlertReport o = findAlerts(other, when(14, 12.0), plain());
  ASSERT_EQ(o.alerts.size(), 2u);
  EXPECT_EQ(o.alerts[0].moved_with, 0u);
  EXPECT_EQ(o.alerts[1].moved_with, 0u);
  EXPECT_LT(o.alerts[1].score_bits, 0.5);
}

TEST(Alerts, BadInputIsRefusedClearly) {
  TemporalMap map(0.05);
  map.add(when(0, 9.0), sessionWith({}));
  map.add(when(0, 15.0), sessionWith({{4, 4}}));
  try {
    findAlerts(map, when(0, 12.0));
    FAIL() << "no session at 12:00";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("no session of the map lies at 2012-03-05T12:00:00"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("the nearest is 2012-03-05T09:00:00"), std::string::npos) << e.what();
  }
  EXPECT_THROW(findAlerts(map, when(0, 15.0) + 0.01), UsageError);  // times match to the half millisecond
  EXPECT_NO_THROW(findAlerts(map, when(0, 15.0) + 1e-7));
  // A session at a time with sub-millisecond digits is found from its printed (rounded) time.
  TemporalMap odd(0.05);
  odd.add(when(0, 9.0), sessionWith({}));
  const double t = when(0, 15.0) + 0.9501126;
  odd.add(t, sessionWith({{4, 4}}));
  const std::string printed = formatTime(t);
  EXPECT_EQ(printed.substr(printed.size() - 5), ".950Z");
  EXPECT_EQ(findAlerts(odd, parseTime(printed)).time_s, t);
  EXPECT_THROW(findAlerts(map, when(0, 9.0)), UsageError);  // the first session: no history
  AlertSettings s = plain();
  s.neighbourhood_voxels = 7;
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  s = plain();
  s.history_to_s = when(0, 8.0);
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  s = plain();
  s.max_voxels_per_object = 0;
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  s = plain();
  s.evidence.all_hours_observations = 0.0;
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  s = plain();
  s.evidence.other_kind_weight = 1.5;
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  s = plain();
  s.moves.max_size_ratio = 0.5;
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  s = plain();
  s.moves.max_colour_distance = std::nan("");
  EXPECT_THROW(findAlerts(map, when(0, 15.0), s), UsageError);
  EXPECT_THROW(findAlerts(TemporalMap(0.05), when(0, 15.0)), UsageError);
}

}  // namespace
}  // namespace chronomap
