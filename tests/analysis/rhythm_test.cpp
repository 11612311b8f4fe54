// Temporal models of the 4D map (analysis/rhythm.h): analytic histories with known answers,
// unobserved sessions as no evidence, a brute-force check of the periodic fit, saved models.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>

#include "builders.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/core/error.h"

namespace chronomap {
namespace {

using test::at;
using test::freeVoxel;
using test::occupiedVoxel;

using test::kHour;
using test::kMonday_s;

/// Occupied every weekday from 9:00 to 17:00 (UTC), free otherwise.
bool officeHours(double t) {
  const double since = t - kMonday_s;
  const auto day = static_cast<int>(std::floor(since / 86400.0));
  const double h = (since - 86400.0 * day) / kHour;
  return day % 7 < 5 && h >= 9.0 && h < 17.0;
}

/// Two observations a day at random hours for `days` days, of a voxel following `truth`.
VoxelSeries sampled(int days, uint64_t seed, bool (*truth)(double)) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> hour(0.0, 12.0);
  VoxelSeries s;
  for (int d = 0; d < days; ++d) {
    for (int half = 0; half < 2; ++half) {
      const double t = kMonday_s + 86400.0 * d + kHour * (hour(rng) + 12.0 * half);
      s.ranks.push_back(static_cast<uint32_t>(s.ranks.size()));
      s.times_s.push_back(t);
      s.occupied.push_back(truth(t) ? 1 : 0);
    }
  }
  return s;
}

double predict(const VoxelRhythm& v, RhythmModel m, int day, double hour) {
  return RhythmModels::predict(v, m, kMonday_s + 86400.0 * day + kHour * hour);
}

TEST(Rhythm, OfficeHoursAreLearnedByTheDailyModels) {
  const VoxelRhythm v = fitVoxel(sampled(28, 1, officeHours));
  // Week 5: Monday 13:00 occupied, Monday 03:00 and Saturday 13:00 free.
  for (RhythmModel m : {RhythmModel::Hourly, RhythmModel::Combined}) {
    EXPECT_GT(predict(v, m, 28, 13.0), 0.75) << toString(m);
    EXPECT_LT(predict(v, m, 28, 3.0), 0.15) << toString(m);
    EXPECT_LT(predict(v, m, 33, 13.0), 0.3) << toString(m);
  }
  // The periodic model finds the daily component first and ranks noon above night.
  EXPECT_EQ(kRhythmPeriods_h[v.period[0]], 24.0);
  EXPECT_GT(predict(v, RhythmModel::Periodic, 28, 13.0), predict(v, RhythmModel::Periodic, 28, 1.0) + 0.3);
  // The mean is the share of occupied observations; a static map repeats the last one.
  double share = 0;
  const VoxelSeries s = sampled(28, 1, officeHours);
  for (uint8_t y : s.occupied) share += y;
  EXPECT_FLOAT_EQ(v.mean, static_cast<float>(share / static_cast<double>(s.occupied.size())));
  EXPECT_EQ(predict(v, RhythmModel::Latest, 28, 13.0), s.occupied.back());
}

TEST(Rhythm, TheHourlyProfileKeepsAScheduleEdgeTheDataShow) {
  // A door's open panel: occupied on weekdays 08:00-18:00, seen twice in each of the two-hour
  // bins 12-14, 14-16 and 16-18 h (occupied) and 18-20 and 20-22 h (free); mean 0.6.
  VoxelSeries s;
  for (double hour : {12.5, 14.5, 16.5, 19.0, 21.0}) {
    for (int day : {0, 1}) {
      s.ranks.push_back(static_cast<uint32_t>(s.ranks.size()));
      s.times_s.push_back(kMonday_s + 86400.0 * day + kHour * hour);
      s.occupied.push_back(hour < 18.0 ? 1 : 0);
    }
  }
  const VoxelRhythm v = fitVoxel(s);
  ASSERT_FLOAT_EQ(v.mean, 0.6f);
  // Wednesday 17:30: the own bin (2 of 2) plus the agreeing bins 14-16 (weight 0.25) and 12-14
  // (0.05); the disagreeing 18-20 and 20-22 h bins count nothing, the pseudo-observation 0.6:
  // (0.6 + 2 + 0.5 + 0.1) / (1 + 2 + 0.5 + 0.1). Smoothing them in alike (weights 0.5 and 0.15,
  // as before) gave 3.9 / 5.6 = 0.70: a door about to shut read as half open an hour before.
  EXPECT_NEAR(predict(v, RhythmModel::Hourly, 2, 17.5), 3.2 / 3.6, 1e-6);
  // 18:30: the own bin (0 of 2) and 20-22 h agree, the occupied bins before count nothing.
  EXPECT_NEAR(predict(v, RhythmModel::Hourly, 2, 18.5), 0.6 / 3.5, 1e-6);
  // 10:30, a bin never observed: both neighbours on its side are borrowed at their weights.
  EXPECT_NEAR(predict(v, RhythmModel::Hourly, 2, 10.5), (0.6 + 0.5 + 0.1) / (1 + 0.5 + 0.1), 1e-6);
  // A neighbour that half agrees counts half: one of the two 16-18 h observations free.
  s.occupied[5] = 0;
  const VoxelRhythm half = fitVoxel(s);
  const double m = half.mean;  // 0.5
  EXPECT_NEAR(predict(half, RhythmModel::Hourly, 2, 17.5),
              (m + 1 + 0.25 * 0.5 * 2 + 0.05 * 0.5 * 2) / (1 + 2 + 0.25 * 0.5 * 2 + 0.05 * 0.5 * 2 + 0.5 * 0.25 * 2 +
                                                             0.5 * 0.05 * 2),
              1e-6);
}

TEST(Rhythm, CombinedKeepsTheMeanForAVoxelWithoutRhythm) {
  // Occupied at random in 60% of the observations, whatever the hour: the hourly profile only
  // fits noise, and leaving each observation out shows it.
  static std::mt19937_64 coin(11);
  const VoxelRhythm noise = fitVoxel(sampled(28, 2, [](double) { return coin() % 10 < 6; }));
  EXPECT_EQ(noise.combined_uses_mean, 1);
  const double far = noise.last_time_s + 1000 * kHour;  // the Markov part has faded
  EXPECT_NEAR(RhythmModels::predict(noise, RhythmModel::Combined, far), noise.mean, 1e-6);
  const VoxelRhythm office = fitVoxel(sampled(28, 1, officeHours));
  EXPECT_EQ(office.combined_uses_mean, 0);
}

/// `s` with counters for every observation: `hits` over `occupied_m` of ray where it was
/// occupied, no hit over `free_m` where it was free.
VoxelSeries withCounters(VoxelSeries s, uint32_t hits, float occupied_m, float free_m) {
  for (uint8_t y : s.occupied) {
    VoxelCounters c;
    c.hits = y ? hits : 0;
    c.length_m = y ? occupied_m : free_m;
    s.counters.push_back(c);
  }
  return s;
}

TEST(Rhythm, CombinedGivesAVoxelWithoutRhythmTheSurfaceEvidenceOfItsCounters) {
  // Both voxels are occupied in a random 40% of the sessions, whatever the hour (the mean wins).
  // One holds a surface that only clips it: 2 hits over 1 cm of ray when the viewpoint sees the
  // surface, 30 cm of rays through its empty part when not. The other lies in front of a
  // surface and catches a noisy hit among 1 m of rays now and then (still P > 0.5 that time).
  static std::mt19937_64 coin(5);
  const VoxelSeries noise = sampled(28, 4, [](double) { return coin() % 10 < 4; });
  double occupied = 0;
  for (uint8_t y : noise.occupied) occupied += y;
  const double n = static_cast<double>(noise.occupied.size());
  const double far = noise.times_s.back() + 1000 * kHour;  // the Markov part has faded
  const VoxelRhythm clipped = fitVoxel(withCounters(noise, 2, 0.01f, 0.3f), 0.05);
  const VoxelRhythm spill = fitVoxel(withCounters(noise, 1, 1.0f, 1.0f), 0.05);
  ASSERT_EQ(clipped.combined_uses_mean, 1);
  ASSERT_EQ(spill.combined_uses_mean, 1);
  // Hits per voxel length of ray: hits x 0.05 m / length, pooled over the observations.
  const double x_clipped = 2 * occupied * 0.05 / (0.01 * occupied + 0.3 * (n - occupied));
  const double x_spill = occupied * 0.05 / n;
  EXPECT_NEAR(clipped.hits_per_voxel, x_clipped, 1e-5);
  EXPECT_NEAR(spill.hits_per_voxel, x_spill, 1e-6);
  auto evidence = [](double x) { return x * x / (x * x + kSurfaceHitsPerVoxel * kSurfaceHitsPerVoxel); };
  EXPECT_NEAR(RhythmModels::predict(clipped, RhythmModel::Combined, far), evidence(x_clipped), 1e-5);
  EXPECT_NEAR(RhythmModels::predict(spill, RhythmModel::Combined, far), evidence(x_spill), 1e-5);
  EXPECT_GT(RhythmModels::predict(clipped, RhythmModel::Combined, far), 0.8);  // the mean is 0.4
  EXPECT_LT(RhythmModels::predict(spill, RhythmModel::Combined, far), 0.1);
  // The other models do not read the counters; a cube's ray length is in its own edges.
  EXPECT_FLOAT_EQ(clipped.mean, spill.mean);
  EXPECT_EQ(RhythmModels::predict(clipped, RhythmModel::Hourly, far),
            RhythmModels::predict(spill, RhythmModel::Hourly, far));
  VoxelSeries cube = withCounters(noise, 1, 1.0f, 1.0f);
  cube.level = 1;
  EXPECT_NEAR(fitVoxel(cube, 0.05).hits_per_voxel, 2 * x_spill, 1e-6);
  // Hits on a ray that ended on the entry face (no length): certainly a surface.
  EXPECT_NEAR(surfaceEvidence(fitVoxel(withCounters(noise, 1, 0.0f, 0.0f), 0.05)), 1.0, 1e-9);
}

TEST(Rhythm, MarkovRatesComeBack) {
  // A two-state chain with entry rate 0.1/h and exit rate 0.3/h, observed every half hour for
  // two years: the estimated rates are the true ones.
  const double in = 0.1, out = 0.3;
  std::mt19937_64 rng(7);
  std::exponential_distribution<double> to_occupied(in), to_free(out);
  VoxelSeries s;
  bool state = false;
  double t = kMonday_s, next_flip = t + kHour * to_occupied(rng);
  for (int i = 0; i < 2 * 24 * 730; ++i, t += 0.5 * kHour) {
    while (next_flip <= t) {
      state = !state;
      next_flip += kHour * (state ? to_free(rng) : to_occupied(rng));
    }
    s.ranks.push_back(static_cast<uint32_t>(i));
    s.times_s.push_back(t);
    s.occupied.push_back(state ? 1 : 0);
  }
  const VoxelRhythm v = fitVoxel(s);
  // Half-hour sampling misses flips that undo each other within a step, which lowers both
  // estimates by a few per cent.
  EXPECT_NEAR(v.rate_in_per_h, in, 0.15 * in);
  EXPECT_NEAR(v.rate_out_per_h, out, 0.15 * out);
  // Far from the last observation the chain forgets it: the stationary probability in/(in+out).
  EXPECT_NEAR(RhythmModels::predict(v, RhythmModel::Markov, v.last_time_s + 1000 * kHour), in / (in + out), 0.03);
  // Right at the last observation it is that observation.
  EXPECT_NEAR(RhythmModels::predict(v, RhythmModel::Markov, v.last_time_s), v.last_occupied, 1e-9);
}

/// Brute force: the squared residual left by a least-squares sinusoid of `period_h` on `r`.
double residualAfter(const VoxelSeries& s, const std::vector<double>& r, double period_h) {
  Eigen::MatrixXd A(static_cast<Eigen::Index>(r.size()), 2);
  Eigen::VectorXd b(static_cast<Eigen::Index>(r.size()));
  const double w = 2.0 * std::numbers::pi / (period_h * kHour);
  for (size_t i = 0; i < r.size(); ++i) {
    A(static_cast<Eigen::Index>(i), 0) = std::cos(w * s.times_s[i]);
    A(static_cast<Eigen::Index>(i), 1) = std::sin(w * s.times_s[i]);
    b(static_cast<Eigen::Index>(i)) = r[i];
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  return (A * x - b).squaredNorm();
}

TEST(Rhythm, PeriodicFitPicksThePeriodThatLeavesTheLeastResidual) {
  for (uint64_t seed = 0; seed < 20; ++seed) {
    std::mt19937_64 rng(seed);
    const double phase = std::uniform_real_distribution<double>(0.0, 24.0)(rng);
    const double period = kRhythmPeriods_h[seed % kRhythmPeriods_h.size()];
    // A random voxel occupied in part of a cycle of one of the periods, with 10% noise.
    VoxelSeries s;
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < 60; ++i) {
      const double t = kMonday_s + kHour * (u(rng) * 24.0 * 30.0);
      const double cycle = std::fmod((t - kMonday_s) / kHour + phase, period) / period;
      s.ranks.push_back(static_cast<uint32_t>(i));
      s.times_s.push_back(t);
      s.occupied.push_back(((cycle < 0.4) != (u(rng) < 0.1)) ? 1 : 0);
    }
    std::sort(s.times_s.begin(), s.times_s.end());
    const VoxelRhythm v = fitVoxel(s);
    double mean = 0;
    for (uint8_t y : s.occupied) mean += y;
    mean /= static_cast<double>(s.occupied.size());
    std::vector<double> r;
    for (uint8_t y : s.occupied) r.push_back(y - mean);
    ASSERT_LT(v.period[0], kRhythmPeriods_h.size());
    const double chosen = residualAfter(s, r, kRhythmPeriods_h[v.period[0]]);
    for (double p : kRhythmPeriods_h) EXPECT_LE(chosen, residualAfter(s, r, p) + 1e-9) << "seed " << seed;
  }
}

/// A map of one voxel observed in some sessions: `seen[i]` whether session i observed it, and
/// then occupied or free by `occupied[i]`. Another voxel is observed in every session.
TemporalMap mapOf(const std::vector<bool>& seen, const std::vector<bool>& occupied, const std::vector<double>& times) {
  TemporalMap map(0.05);
  for (size_t i = 0; i < seen.size(); ++i) {
    SessionMap s(0.05);
    s.add(at(0, 0, 0), freeVoxel());
    if (seen[i]) s.add(at(5, 5, 5), occupied[i] ? occupiedVoxel(Rgb{}) : freeVoxel());
    map.add(times[i], s);
  }
  return map;
}

TEST(Rhythm, SessionsThatDidNotObserveAVoxelAreNoEvidence) {
  const std::vector<double> times = {0, 10 * kHour, 20 * kHour, 30 * kHour, 40 * kHour, 50 * kHour};
  const std::vector<bool> occupied = {false, true, false, true, true, false};
  // Sessions 2 and 4 did not see the voxel: the map keeps its last state, the series skips them.
  const TemporalMap map = mapOf({true, true, false, true, false, true}, occupied, times);
  const std::vector<VoxelSeries> series = observedSeries(map, 0, 6);
  ASSERT_EQ(series.size(), 1u);
  EXPECT_EQ(series[0].corner, at(5, 5, 5));
  EXPECT_EQ(series[0].ranks, (std::vector<uint32_t>{0, 1, 3, 5}));
  EXPECT_EQ(series[0].occupied, (std::vector<uint8_t>{0, 1, 1, 0}));
  ASSERT_EQ(series[0].counters.size(), 4u);  // the counters stored for each observation
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(series[0].counters[i].state() == VoxelState::Occupied, series[0].occupied[i] == 1) << i;
  }
  // The same observations without the blind sessions fit the same model.
  const TemporalMap seen_only = mapOf({true, true, true, true}, {false, true, true, false},
                                      {times[0], times[1], times[3], times[5]});
  const RhythmModels a = fitRhythm(map, 0, 1e9), b = fitRhythm(seen_only, 0, 1e9);
  ASSERT_EQ(a.voxels.size(), 1u);
  ASSERT_EQ(b.voxels.size(), 1u);
  for (RhythmModel m : kRhythmModels) {
    for (double t : {5 * kHour, 45 * kHour, 500 * kHour}) {
      EXPECT_DOUBLE_EQ(RhythmModels::predict(a.voxels[0], m, t), RhythmModels::predict(b.voxels[0], m, t));
    }
  }
  EXPECT_EQ(a.voxels[0].observations, 4);
  // Learning from a range: sessions outside it are not read.
  const RhythmModels early = fitRhythm(map, 0, 15 * kHour);
  EXPECT_EQ(early.sessions, 2u);
  ASSERT_EQ(early.voxels.size(), 1u);
  EXPECT_EQ(early.voxels[0].observations, 2);
  EXPECT_THROW(fitRhythm(map, 1e8, 1e9), UsageError);
  EXPECT_THROW(fitRhythm(map, 0, 1e9, 0), UsageError);
  // A voxel that never changed has no model; find() answers per voxel.
  EXPECT_EQ(a.find(at(0, 0, 0)), nullptr);
  ASSERT_NE(a.find(at(5, 5, 5)), nullptr);
  EXPECT_EQ(a.find(at(5, 5, 5))->corner, at(5, 5, 5));
}

TEST(Rhythm, SavedModelsAnswerTheSameAndBadBytesAreRefused) {
  RhythmModels m;
  m.from_s = kMonday_s;
  m.to_s = kMonday_s + 28 * 86400.0;
  m.sessions = 56;
  for (int i = 0; i < 50; ++i) {
    VoxelSeries s = sampled(28, static_cast<uint64_t>(i), officeHours);
    s.corner = at(i, 2 * i, 3);
    m.voxels.push_back(fitVoxel(s));
  }
  std::sort(m.voxels.begin(), m.voxels.end(),
            [](const VoxelRhythm& a, const VoxelRhythm& b) { return mortonEncode(a.corner) < mortonEncode(b.corner); });
  const std::vector<uint8_t> bytes = serialize(m);
  EXPECT_EQ(bytes.size(), m.bytes());
  const RhythmModels back = deserializeRhythm(bytes, "m.rhythm");
  ASSERT_EQ(back.voxels.size(), m.voxels.size());
  EXPECT_EQ(back.sessions, 56u);
  for (size_t i = 0; i < m.voxels.size(); ++i) {
    for (RhythmModel model : kRhythmModels) {
      for (double h : {3.0, 13.0, 100.0}) {
        const double t = kMonday_s + 29 * 86400.0 + h * kHour;
        EXPECT_EQ(RhythmModels::predict(back.voxels[i], model, t), RhythmModels::predict(m.voxels[i], model, t));
      }
    }
  }
  EXPECT_EQ(serialize(back), bytes);
  // A version 1 model (97 bytes a voxel, no hit density) still reads; Combined keeps the mean.
  {
    VoxelSeries s = withCounters(sampled(28, 9, officeHours), 3, 0.02f, 0.5f);
    RhythmModels one;
    one.voxels.push_back(fitVoxel(s));
    const std::vector<uint8_t> v1 = serialize(one, 1);
    ASSERT_EQ(v1.size(), 44 + RhythmModels::kVoxelBytes - 8);  // no group, no hits_per_voxel, no group count
    EXPECT_EQ(v1[4], 1);                                          // the version, little-endian after the magic
    const RhythmModels old = deserializeRhythm(v1, "v1.rhythm");
    ASSERT_EQ(old.voxels.size(), 1u);
    EXPECT_EQ(old.voxels[0].hits_per_voxel, -1.0f);
    EXPECT_EQ(old.voxels[0].mean, one.voxels[0].mean);
    EXPECT_EQ(surfaceEvidence(old.voxels[0]), static_cast<double>(one.voxels[0].mean));
    // A hit density that is not a number, negative (other than version 1's -1) or beyond the cap
    // is refused.
    const std::vector<uint8_t> v3 = serialize(one);
    for (float bad : {std::numeric_limits<float>::quiet_NaN(), -0.5f, 2e6f, std::numeric_limits<float>::infinity()}) {
      std::vector<uint8_t> c = v3;
      std::memcpy(c.data() + c.size() - 8 - 4 - 4, &bad, 4);
      try {
        deserializeRhythm(c, "bad.rhythm");
        ADD_FAILURE() << bad;
      } catch (const FormatError& e) {
        EXPECT_NE(std::string(e.what()).find("bad.rhythm: bad hit density"), std::string::npos) << e.what();
      }
    }
  }
  // Every truncation and a wrong magic are refused with the name; random corruption either is
  // refused or reads as a model that serialises back to those bytes.
  for (size_t n = 0; n < bytes.size(); n += 7) {
    EXPECT_THROW(deserializeRhythm(std::span(bytes.data(), n), "m.rhythm"), FormatError) << n;
  }
  std::vector<uint8_t> bad = bytes;
  bad[0] = 'X';
  try {
    deserializeRhythm(bad, "m.rhythm");
    FAIL();
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("m.rhythm"), std::string::npos);
  }
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 500; ++trial) {
    std::vector<uint8_t> c = bytes;
    c[rng() % c.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
    try {
      EXPECT_EQ(serialize(deserializeRhythm(c, "c")), c);
    } catch (const FormatError&) {
    }
  }
}

TEST(Rhythm, PredictedMapsCarryTheModelsProbabilities) {
  // A voxel occupied in office hours, seen by two sessions a day for four weeks, beside a wall
  // voxel that never changes.
  const VoxelSeries plan = sampled(28, 4, officeHours);
  TemporalMap map(0.05);
  for (size_t i = 0; i < plan.times_s.size(); ++i) {
    SessionMap s(0.05);
    s.add(at(0, 0, 0), occupiedVoxel(Rgb{200, 10, 10}));
    s.add(at(5, 5, 5), plan.occupied[i] ? occupiedVoxel(Rgb{10, 200, 10}) : freeVoxel());
    map.add(plan.times_s[i], s);
  }
  const RhythmModels models = fitRhythm(map, 0, 1e12);
  ASSERT_EQ(models.voxels.size(), 1u);
  const double monday_13 = kMonday_s + 28 * 86400.0 + 13 * kHour, monday_3 = kMonday_s + 28 * 86400.0 + 3 * kHour;
  for (RhythmModel m : kRhythmModels) {
    for (double t : {monday_13, monday_3}) {
      const SessionMap p = predictMap(map, models, m, t);
      const auto c = p.find(at(5, 5, 5));
      ASSERT_TRUE(c);
      EXPECT_NEAR(c->probability(), RhythmModels::predict(models.voxels[0], m, t), 1e-6) << toString(m);
      if (c->hits > 0) {
        EXPECT_EQ(c->meanColour(), (Rgb{10, 200, 10}));  // the last colour seen there
      }
      // The wall is as last observed.
      EXPECT_EQ(p.stateOf(at(0, 0, 0)), VoxelState::Occupied);
      EXPECT_EQ(p.find(at(0, 0, 0))->meanColour(), (Rgb{200, 10, 10}));
      EXPECT_EQ(p.stateOf(at(9, 9, 9)), VoxelState::Unknown);
    }
  }
  EXPECT_EQ(predictMap(map, models, RhythmModel::Hourly, monday_13).stateOf(at(5, 5, 5)), VoxelState::Occupied);
  EXPECT_EQ(predictMap(map, models, RhythmModel::Hourly, monday_3).stateOf(at(5, 5, 5)), VoxelState::Free);
  RhythmModels other = models;
  other.resolution_m = 0.1;
  EXPECT_THROW(predictMap(map, other, RhythmModel::Hourly, monday_3), UsageError);
}

TEST(Rhythm, ModelNamesRoundTrip) {
  for (RhythmModel m : kRhythmModels) EXPECT_EQ(parseRhythmModel(toString(m)), m);
  EXPECT_THROW(parseRhythmModel("fourier"), UsageError);
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

/// A door of 4 x 4 voxels in the plane y = 0, open (free) on weekdays from 8:00 to 18:00 and
/// shut (occupied) otherwise, observed twice a day at random hours for four weeks. Voxel (1, 0,
/// 1) is blurred by pose error: seen in every third session only, and when the door is open still
/// occupied in a random half of them (kBlur in 10). Beside the door, voxel (4, 0, 1) is a clipped
/// wall: occupied in a random 40% of the sessions whatever the hour. Every occupied observation is
/// hit densely (2 hits over 1 cm of ray); a free one is crossed by 30 cm of rays without a hit.
constexpr int kBlur = 5;
std::vector<VoxelSeries> doorSeries() {
  const auto open = [](double t) {
    const double since = t - kMonday_s;
    const auto day = static_cast<int>(std::floor(since / 86400.0));
    const double h = (since - 86400.0 * day) / kHour;
    return day % 7 < 5 && h >= 8.0 && h < 18.0;
  };
  const VoxelSeries times = sampled(28, 21, officeHours);  // only its times and ranks are used
  std::mt19937_64 rng(8);
  std::vector<VoxelSeries> out;
  for (int x = 0; x <= 4; ++x) {
    for (int z = 0; z < 4; ++z) {
      if (x == 4 && z != 1) continue;
      VoxelSeries s;
      s.corner = at(x, 0, z);
      const bool blurred = x == 1 && z == 1, wall = x == 4;
      for (size_t i = 0; i < times.times_s.size(); ++i) {
        if (blurred && i % 3 != 0) continue;  // seen in every third session only
        const double t = times.times_s[i];
        const bool y = wall ? rng() % 10 < 4 : (!open(t) || (blurred && rng() % 10 < kBlur));
        s.ranks.push_back(times.ranks[i]);
        s.times_s.push_back(t);
        s.occupied.push_back(y ? 1 : 0);
      }
      out.push_back(withCounters(s, 2, 0.01f, 0.3f));
    }
  }
  return out;
}

const VoxelRhythm& voxelAt(const RhythmModels& m, int x, int z) {
  const VoxelRhythm* v = m.find(at(x, 0, z));
  EXPECT_NE(v, nullptr);
  return *v;
}

TEST(Rhythm, ADoorsVoxelsArePredictedAsOneObject) {
  const std::vector<VoxelSeries> series = doorSeries();
  RhythmGroupSettings off;
  off.enabled = false;
  const RhythmModels alone = fitSeries(series, 0.05, off), grouped = fitSeries(series, 0.05);
  ASSERT_EQ(grouped.voxels.size(), 17u);
  const double monday_noon = kMonday_s + 28 * 86400.0 + 13 * kHour, monday_night = monday_noon - 10 * kHour;
  // Alone, the blurred voxel's hourly profile loses to its mean (leave-one-out), so Combined
  // gives it its surface evidence: a wall, shut at noon, which closes the doorway.
  const VoxelRhythm& blurred_alone = voxelAt(alone, 1, 1);
  EXPECT_EQ(blurred_alone.combined_uses_mean, 1);
  EXPECT_EQ(blurred_alone.group, VoxelRhythm::kNoGroup);
  EXPECT_GT(RhythmModels::predict(blurred_alone, RhythmModel::Combined, monday_noon), 0.9);
  // Grouped with the door's other voxels (they change together), it takes the door's pooled
  // profile: open at noon on a weekday, shut at night.
  ASSERT_EQ(grouped.groups.size(), 1u);
  const VoxelRhythm& blurred = voxelAt(grouped, 1, 1);
  EXPECT_EQ(blurred.group, 0u);
  EXPECT_LT(RhythmModels::predict(blurred, RhythmModel::Combined, monday_noon), 0.35);
  EXPECT_GT(RhythmModels::predict(blurred, RhythmModel::Combined, monday_night), 0.8);
  // The object's profile is its voxels' hour bins summed.
  uint32_t observed = 0;
  for (const VoxelSeries& s : series) observed += s.corner != at(4, 0, 1) ? static_cast<uint32_t>(s.times_s.size()) : 0;
  uint32_t pooled = 0;
  for (const auto& kind : grouped.groups[0].observed) {
    for (uint16_t n : kind) pooled += n;
  }
  EXPECT_EQ(pooled, observed);
  // The clipped wall beside it changes at random, not with the door: it stays out of the object
  // and keeps its surface evidence.
  const VoxelRhythm& wall = voxelAt(grouped, 4, 1);
  EXPECT_EQ(wall.group, VoxelRhythm::kNoGroup);
  EXPECT_EQ(RhythmModels::predict(wall, RhythmModel::Combined, monday_noon),
            RhythmModels::predict(voxelAt(alone, 4, 1), RhythmModel::Combined, monday_noon));
  // Every clean voxel of the door is predicted as the door too.
  for (int x = 0; x < 4; ++x) {
    for (int z = 0; z < 4; ++z) {
      EXPECT_LT(RhythmModels::predict(voxelAt(grouped, x, z), RhythmModel::Combined, monday_noon), 0.35) << x << z;
      EXPECT_GT(RhythmModels::predict(voxelAt(grouped, x, z), RhythmModel::Combined, monday_night), 0.8) << x << z;
    }
  }
  // An object whose pooled profile is no better than its pooled mean is no object with a rhythm.
  RhythmGroupSettings strict;
  strict.min_gain = 0.999;
  EXPECT_TRUE(fitSeries(series, 0.05, strict).groups.empty());
}

TEST(Rhythm, SavedModelsKeepTheirObjects) {
  RhythmModels m = fitSeries(doorSeries(), 0.05);
  ASSERT_FALSE(m.groups.empty());
  const std::vector<uint8_t> bytes = serialize(m);
  EXPECT_EQ(bytes.size(), m.bytes());
  EXPECT_EQ(bytes.size(), RhythmModels::kHeaderBytes + 17 * RhythmModels::kVoxelBytes + 8 +
                              m.groups.size() * RhythmModels::kGroupBytes);
  const RhythmModels back = deserializeRhythm(bytes, "door.rhythm");
  ASSERT_EQ(back.voxels.size(), m.voxels.size());
  for (size_t i = 0; i < m.voxels.size(); ++i) {
    EXPECT_EQ(back.voxels[i].group, m.voxels[i].group);
    for (double h : {3.0, 13.0, 100.0}) {
      const double t = kMonday_s + 29 * 86400.0 + h * kHour;
      EXPECT_EQ(RhythmModels::predict(back.voxels[i], RhythmModel::Combined, t),
                RhythmModels::predict(m.voxels[i], RhythmModel::Combined, t));
    }
  }
  EXPECT_EQ(serialize(back), bytes);
  // A voxel naming a group the file lacks, and a group with more occupied than observed, are refused.
  const size_t first_group = bytes.size() - m.groups.size() * RhythmModels::kGroupBytes;
  const size_t group_field = RhythmModels::kHeaderBytes + RhythmModels::kVoxelBytes - 4;  // the first voxel's
  std::vector<uint8_t> bad = bytes;
  const uint32_t missing = static_cast<uint32_t>(m.groups.size());
  std::memcpy(bad.data() + group_field, &missing, 4);
  EXPECT_THROW(deserializeRhythm(bad, "bad.rhythm"), FormatError);
  bad = bytes;
  const uint16_t too_many = 0xffff;
  std::memcpy(bad.data() + first_group + 2, &too_many, 2);  // the first bin's occupied count
  ASSERT_LT(m.groups[0].observed[0][0], too_many);
  EXPECT_THROW(deserializeRhythm(bad, "bad.rhythm"), FormatError);
  // A version 2 file (no group per voxel, no table) still reads: Combined as before objects.
  RhythmGroupSettings off;
  off.enabled = false;
  const RhythmModels alone = fitSeries(doorSeries(), 0.05, off);
  const std::vector<uint8_t> v2 = serialize(alone, 2);
  ASSERT_EQ(v2.size(), 44 + alone.voxels.size() * (RhythmModels::kVoxelBytes - 4));  // no groups
  const RhythmModels old = deserializeRhythm(v2, "v2.rhythm");
  ASSERT_EQ(old.voxels.size(), alone.voxels.size());
  EXPECT_TRUE(old.groups.empty());
  for (size_t i = 0; i < old.voxels.size(); ++i) {
    EXPECT_EQ(old.voxels[i].group, VoxelRhythm::kNoGroup);
    EXPECT_EQ(RhythmModels::predict(old.voxels[i], RhythmModel::Combined, kMonday_s + 29 * 86400.0),
              RhythmModels::predict(alone.voxels[i], RhythmModel::Combined, kMonday_s + 29 * 86400.0));
  }
  // Version 5 is not read.
  std::vector<uint8_t> v5 = bytes;
  v5[4] = 5;
  EXPECT_THROW(deserializeRhythm(v5, "v5.rhythm"), FormatError);
}

}  // namespace
}  // namespace chronomap
