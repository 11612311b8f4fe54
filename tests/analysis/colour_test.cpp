// Colour by time of day (analysis/colour.h): a known illumination curve recovered, the fit
// against a slow reference (the truncated SVD of the full colour matrix), the lighting-invariant
// colour test on an analytic sunset against a repaint, end to end through a 4D map, bad input.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "builders.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/core/error.h"

namespace chronomap {
namespace {

using test::at;
using test::occupiedVoxel;

using test::kMonday_s;

/// An analytic day: a dim night light, lamps from 7 to 19, and a sun that is warm when low.
std::array<double, 3> sunsetLight(double hour) {
  const double lamps = hour >= 7.0 && hour < 19.0 ? 0.5 : 0.05;
  const double e = hour > 6.0 && hour < 20.0 ? std::sin(std::numbers::pi * (hour - 6.0) / 14.0) : 0.0;
  return {lamps + 0.6 * e, lamps + 0.6 * e * (0.6 + 0.4 * e), lamps + 0.6 * e * (0.3 + 0.7 * e)};
}

/// Observations of every voxel at every whole hour: colour = albedo * light(hour), exactly.
std::vector<ColourObservation> fullDay(const std::vector<std::array<double, 3>>& albedo,
                                       const std::function<std::array<double, 3>(size_t, double)>& colour) {
  std::vector<ColourObservation> obs;
  for (size_t v = 0; v < albedo.size(); ++v) {
    for (int h = 0; h < 24; ++h) {
      ColourObservation o;
      o.voxel = static_cast<uint32_t>(v);
      o.hour = h;
      o.rgb = colour(v, h);
      obs.push_back(o);
    }
  }
  return obs;
}

TEST(Colour, OneLightRecoversAKnownIlluminationCurve) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(20.0, 160.0);
  std::vector<std::array<double, 3>> albedo(40);
  for (auto& a : albedo) a = {u(rng), u(rng), u(rng)};
  const auto obs = fullDay(albedo, [&](size_t v, double h) {
    const auto l = sunsetLight(h);
    return std::array<double, 3>{albedo[v][0] * l[0], albedo[v][1] * l[1], albedo[v][2] * l[2]};
  });
  ColourSettings s;
  s.components = 1;
  s.smoothness = 0.0;
  s.iterations = 30;
  const ColourModel m = fitColourObservations(obs, albedo.size(), s);
  // The curve is known up to its scale: the model's peaks at 1.
  for (int c = 0; c < 3; ++c) {
    double peak = 0.0;
    for (int h = 0; h < 24; ++h) peak = std::max(peak, sunsetLight(h)[static_cast<size_t>(c)]);
    for (int h = 0; h < 24; ++h) {
      EXPECT_NEAR(m.curve(0, c, h), sunsetLight(h)[static_cast<size_t>(c)] / peak, 1e-6) << "channel " << c << " hour " << h;
    }
  }
  EXPECT_LT(m.rms_error, 1e-4);
  // Each voxel's weight is its albedo times the curve's peak: predictions are exact at any knot.
  for (size_t v = 0; v < albedo.size(); ++v) {
    const auto p = m.predict(v, 18.0);
    const auto l = sunsetLight(18.0);
    for (size_t c = 0; c < 3; ++c) EXPECT_NEAR(p[c], albedo[v][c] * l[c], 1e-5 * albedo[v][c] * l[c] + 1e-9);  // the ridge: 1e-6
  }
  // Between knots the curve is linear.
  EXPECT_NEAR(m.curve(0, 0, 18.5), 0.5 * (m.curve(0, 0, 18.0) + m.curve(0, 0, 19.0)), 1e-12);
  EXPECT_NEAR(m.curve(0, 1, 23.5), 0.5 * (m.curve(0, 1, 23.0) + m.curve(0, 1, 0.0)), 1e-12);  // wraps at midnight
}

TEST(Colour, TwoLightsMixedPerVoxelArePredictedExactly) {
  // Lamps everywhere, daylight in proportion to how near a window a voxel is.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(20.0, 160.0), w(0.0, 1.0);
  std::vector<std::array<double, 3>> albedo(60);
  std::vector<double> window(albedo.size());
  for (size_t v = 0; v < albedo.size(); ++v) {
    albedo[v] = {u(rng), u(rng), u(rng)};
    window[v] = w(rng);
  }
  auto light = [&](size_t v, double h) {
    const double lamps = h >= 7.0 && h < 19.0 ? 0.5 : 0.05;
    const double e = h > 6.0 && h < 20.0 ? std::sin(std::numbers::pi * (h - 6.0) / 14.0) : 0.0;
    const std::array<double, 3> sun{e, e * (0.6 + 0.4 * e), e * (0.3 + 0.7 * e)};
    std::array<double, 3> out{};
    for (size_t c = 0; c < 3; ++c) out[c] = albedo[v][c] * (lamps + 0.8 * window[v] * sun[c]);
    return out;
  };
  const auto obs = fullDay(albedo, light);
  ColourSettings s;
  s.components = 2;
  s.smoothness = 0.0;
  s.iterations = 300;
  const ColourModel two = fitColourObservations(obs, albedo.size(), s);
  s.components = 1;
  const ColourModel one = fitColourObservations(obs, albedo.size(), s);
  EXPECT_LT(two.rms_error, 0.05);
  EXPECT_GT(one.rms_error, 1.0);  // one light cannot mix lamps and daylight per voxel
  for (size_t v = 0; v < albedo.size(); v += 7) {
    const auto p = two.predict(v, 17.0), t = light(v, 17.0);
    for (size_t c = 0; c < 3; ++c) EXPECT_NEAR(p[c], t[c], 0.2);
  }
}

/// The slow reference: the best rank-k approximation of the full voxel x hour matrix per
/// channel (Eckart-Young: the truncated SVD), its RMS residual.
double svdReference(const std::vector<ColourObservation>& obs, size_t voxels, int k) {
  double sq = 0.0;
  for (size_t c = 0; c < 3; ++c) {
    Eigen::MatrixXd M(static_cast<Eigen::Index>(voxels), 24);
    for (const ColourObservation& o : obs) M(o.voxel, static_cast<Eigen::Index>(o.hour)) = o.rgb[c];
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(M);
    const Eigen::VectorXd sv = svd.singularValues();
    for (Eigen::Index i = k; i < sv.size(); ++i) sq += sv(i) * sv(i);
  }
  return std::sqrt(sq / (3.0 * static_cast<double>(obs.size())));
}

TEST(Colour, PropertyFitMatchesTheTruncatedSvdOnRandomAlbedosAndCurves) {
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const int k = 1 + static_cast<int>(seed % 2);
    const size_t voxels = 10 + seed * 3;
    // Random positive curves and weights, and noise, so that the data is not exactly rank k.
    std::vector<std::array<double, 3>> albedo(voxels * 2);
    for (auto& a : albedo) a = {30 + 120 * u(rng), 30 + 120 * u(rng), 30 + 120 * u(rng)};
    std::array<std::array<double, 24>, 6> curves{};
    for (auto& curve : curves) {
      for (double& x : curve) x = 0.1 + 0.9 * u(rng);
    }
    std::normal_distribution<double> noise(0.0, 2.0);
    std::vector<std::array<double, 3>> weights(voxels);
    auto obs = fullDay(weights, [&](size_t v, double h) {
      std::array<double, 3> out{};
      for (size_t c = 0; c < 3; ++c) {
        for (int j = 0; j < k; ++j) out[c] += albedo[v * 2 + static_cast<size_t>(j)][c] * curves[static_cast<size_t>(j * 3) + c][static_cast<size_t>(h)] / k;
        out[c] = std::clamp(out[c] + noise(rng), 0.0, 255.0);
      }
      return out;
    });
    ColourSettings s;
    s.components = k;
    s.smoothness = 0.0;
    s.iterations = 400;
    const ColourModel m = fitColourObservations(obs, voxels, s);
    const double reference = svdReference(obs, voxels, k);
    EXPECT_GE(m.rms_error, reference * (1.0 - 1e-6)) << "seed " << seed;
    EXPECT_LE(m.rms_error, reference * 1.01 + 1e-6) << "seed " << seed << " k " << k;
  }
}

TEST(Colour, SmoothnessFillsHoursNeverObserved) {
  // Observed only at even hours: the odd knots follow their neighbours.
  std::vector<ColourObservation> obs;
  for (uint32_t v = 0; v < 5; ++v) {
    for (int h = 0; h < 24; h += 2) {
      const double l = 0.2 + 0.8 * std::max(0.0, std::sin(std::numbers::pi * (h - 6) / 12.0));
      obs.push_back({v, static_cast<double>(h), {100.0 * l, 80.0 * l, 60.0 * l}});
    }
  }
  ColourSettings s;
  s.components = 1;
  s.smoothness = 0.01;
  const ColourModel m = fitColourObservations(obs, 5, s);
  for (int h = 1; h < 23; h += 2) {
    EXPECT_NEAR(m.curve(0, 0, h), 0.5 * (m.curve(0, 0, h - 1) + m.curve(0, 0, h + 1)), 0.03) << h;
  }
}

TEST(Colour, LightingDistanceTellsASunsetFromARepaint) {
  const std::array<double, 3> albedo{120, 110, 100}, paint{40, 140, 60};
  const auto noon = sunsetLight(12.0), sunset = sunsetLight(19.5);
  auto lit = [](const std::array<double, 3>& a, const std::array<double, 3>& l) {
    return Rgb{static_cast<uint8_t>(std::lround(a[0] * l[0])), static_cast<uint8_t>(std::lround(a[1] * l[1])),
               static_cast<uint8_t>(std::lround(a[2] * l[2]))};
  };
  const std::array<double, 3> gain{sunset[0] / noon[0], sunset[1] / noon[1], sunset[2] / noon[2]};
  const Rgb before = lit(albedo, noon), after = lit(albedo, sunset), repainted = lit(paint, sunset);
  // Without the light, the sunset moves the colour far.
  const double raw = std::hypot(double(after.r) - before.r, double(after.g) - before.g, double(after.b) - before.b);
  EXPECT_GT(raw, 40.0);
  EXPECT_LT(lightingDistance(before, after, gain).first, 1.0);
  EXPECT_GT(lightingDistance(before, repainted, gain).first, 40.0);
  // Symmetric: from the sunset back to noon.
  const std::array<double, 3> back{1.0 / gain[0], 1.0 / gain[1], 1.0 / gain[2]};
  EXPECT_LT(lightingDistance(after, before, back).first, 1.0);
  EXPECT_GT(lightingDistance(repainted, before, back).first, 40.0);
  const Rgb expected = lightingDistance(before, after, gain).second;
  EXPECT_NEAR(expected.r, after.r, 1);
  EXPECT_NEAR(expected.b, after.b, 1);
}

/// A 4D map of a 8 x 8 wall of voxels with random albedos under sunsetLight(), two sessions a
/// day for `days` days at the given hours; from session `repaint_at` on, the voxels with x < 3
/// have another albedo.
TemporalMap wallMap(int days, const std::vector<double>& hours, int repaint_at, std::vector<double>& times) {
  TemporalMap map(0.05, ChangeCriterion{0.0, 4.0});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(60.0, 180.0);
  std::vector<std::array<double, 3>> albedo(64);
  for (auto& a : albedo) a = {u(rng), u(rng), u(rng)};
  int session = 0;
  for (int d = 0; d < days; ++d) {
    for (double h : hours) {
      const double t = kMonday_s + 86400.0 * d + 3600.0 * h;
      SessionMap s(0.05);
      for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
          const bool repainted = session >= repaint_at && x < 3;
          const std::array<double, 3> a = repainted ? std::array<double, 3>{200, 40, 40} : albedo[size_t(y * 8 + x)];
          const auto l = sunsetLight(h);
          const Rgb c{static_cast<uint8_t>(std::lround(std::min(255.0, a[0] * l[0]))),
                      static_cast<uint8_t>(std::lround(std::min(255.0, a[1] * l[1]))),
                      static_cast<uint8_t>(std::lround(std::min(255.0, a[2] * l[2])))};
          s.add(at(x, y, 0), occupiedVoxel(c));
        }
      }
      map.add(t, s);
      times.push_back(t);
      ++session;
    }
  }
  return map;
}

TEST(Colour, LightingInvariantDiffEndToEnd) {
  std::vector<double> times;
  const std::vector<double> hours{9.0, 12.0, 16.0, 19.5, 22.0};
  const int days = 6, sessions = days * static_cast<int>(hours.size());
  // The last session (22:00) repaints; compare the day's 12:00 with its 19.5 (a sunset, no
  // repaint) and its 16:00 with 22:00 (night, repainted).
  TemporalMap map = wallMap(days, hours, sessions - 1, times);
  const double noon = times[static_cast<size_t>(sessions - 4)], sunset = times[static_cast<size_t>(sessions - 2)];
  const ColourModel model = fitColour(map, -std::numeric_limits<double>::infinity(), times[static_cast<size_t>(sessions - 2)]);
  EXPECT_EQ(model.keys.size(), 64u);
  ColourDiffSettings raw;
  raw.distance = 15.0;
  ColourDiffSettings invariant = raw;
  invariant.lighting_invariant = true;
  const ColourDiff plain = colourChanges(map, noon, sunset, &model, raw);
  EXPECT_EQ(plain.compared, 64u);
  EXPECT_GT(plain.changes.size(), 48u);  // the sunset changes nearly every colour
  EXPECT_EQ(colourChanges(map, noon, sunset, &model, invariant).changes.size(), 0u);
  // Repainted between the afternoon and the night: at night's light (a twentieth of the day's)
  // the map's colour uncertainty, scaled up to the afternoon's, is large, so only the clearest
  // repainted voxels count; none that kept its paint does.
  const double afternoon = times[static_cast<size_t>(sessions - 3)], night = times[static_cast<size_t>(sessions - 1)];
  const ColourModel before_night = fitColour(map, -std::numeric_limits<double>::infinity(), sunset);
  const ColourDiff d = colourChanges(map, afternoon, night, &before_night, invariant);
  EXPECT_GE(d.changes.size(), 1u);
  EXPECT_LE(d.changes.size(), 24u);
  for (const ColourChange& c : d.changes) EXPECT_LT(c.key.x - at(0, 0, 0).x, 3);
  // Noon to the same evening's sunset of a repainted wall: only the repaint.
  std::vector<double> times2;
  TemporalMap map2 = wallMap(days, hours, sessions - 2, times2);
  const ColourModel m2 = fitColour(map2, -std::numeric_limits<double>::infinity(), times2[static_cast<size_t>(sessions - 3)]);
  EXPECT_EQ(colourChanges(map2, times2[static_cast<size_t>(sessions - 4)], times2[static_cast<size_t>(sessions - 2)], &m2,
                          invariant)
                .changes.size(),
            24u);
}

TEST(Colour, OnlyVoxelsObservedAnewAreCompared) {
  // A wall seen at noon, then only its left half at sunset: the right half keeps its noon colour
  // in the map, which is no observation at sunset, so neither diff compares it (the invariant one
  // would otherwise read the unchanged noon colour as a change against the sunset's light).
  TemporalMap map(0.05, ChangeCriterion{0.0, 4.0});
  std::vector<double> times;
  for (int d = 0; d < 3; ++d) {
    for (double h : {12.0, 19.5}) {
      const bool half = d == 2 && h > 12.0;
      SessionMap s(0.05);
      const auto l = sunsetLight(h);
      for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < (half ? 4 : 8); ++x) {
          s.add(at(x, y, 0), occupiedVoxel(Rgb{static_cast<uint8_t>(std::lround(150 * l[0])),
                                               static_cast<uint8_t>(std::lround(120 * l[1])),
                                               static_cast<uint8_t>(std::lround(100 * l[2]))}));
        }
      }
      times.push_back(kMonday_s + 86400.0 * d + 3600.0 * h);
      map.add(times.back(), s);
    }
  }
  const ColourModel m = fitColour(map, times.front(), times[4]);
  ColourDiffSettings plain;
  plain.distance = 10.0;
  ColourDiffSettings inv = plain;
  inv.lighting_invariant = true;
  const ColourDiff a = colourChanges(map, times[4], times[5], &m, plain), b = colourChanges(map, times[4], times[5], &m, inv);
  EXPECT_EQ(a.compared, 32u);
  EXPECT_EQ(a.changes.size(), 32u);  // the sunset
  EXPECT_EQ(b.compared, 32u);
  EXPECT_EQ(b.changes.size(), 0u);
  // The same time twice: nothing observed in between.
  EXPECT_EQ(colourChanges(map, times[5], times[5], &m, plain).compared, 0u);
}

TEST(Colour, RecolourPaintsThePredictedColour) {
  std::vector<double> times;
  TemporalMap map = wallMap(5, {8.0, 13.0, 19.0}, 1000, times);
  const ColourModel m = fitColour(map, times.front(), times.back());
  EXPECT_EQ(m.sessions, times.size());
  const double t = kMonday_s + 86400.0 * 9 + 3600.0 * 13.0;  // a later day at 13:00
  SessionMap extra = map.snapshot(times.back());
  extra.add(at(20, 20, 0), occupiedVoxel(Rgb{1, 2, 3}));  // no model: keeps its colour
  const SessionMap painted = recolour(extra, m, t);
  const auto unmodelled = painted.find(at(20, 20, 0));
  ASSERT_TRUE(unmodelled);
  EXPECT_EQ(unmodelled->meanColour(), (Rgb{1, 2, 3}));
  // At 13:00 each voxel reads as it was observed at 13:00 (within the map's colour distance).
  const SessionMap observed = map.snapshot(times[times.size() - 2]);
  for (int x = 0; x < 8; ++x) {
    const Rgb p = painted.find(at(x, 2, 0))->meanColour(), o = observed.find(at(x, 2, 0))->meanColour();
    EXPECT_LE(std::hypot(double(p.r) - o.r, double(p.g) - o.g, double(p.b) - o.b), 4.0 + 2.0) << x;
  }
  EXPECT_EQ(m.bytesPerVoxel(), 6u + 24u);
  EXPECT_EQ(m.bytes(), 64u * 30u + 8u * 2u * 3u * 24u);
}

TEST(Colour, SavedModelsAnswerTheSameColoursAndBadBytesAreRefused) {
  std::vector<double> times;
  const TemporalMap map = wallMap(5, {8.0, 13.0, 19.0}, 1000, times);
  const ColourModel m = fitColour(map, times.front(), times.back());
  EXPECT_EQ(m.resolution_m, map.resolution_m());
  const std::vector<uint8_t> bytes = serialize(m);
  // An 84-byte header (magic, version, kind, shape, resolution, range, counts, fit error, the
  // map's fingerprint and the number of learning times), the times, the curves, then the
  // voxels: what bytes() counts.
  ASSERT_EQ(m.fitted_on.times_s, times);
  EXPECT_EQ(bytes.size(), 84u + 8u * times.size() + m.bytes());
  const ColourModel back = deserializeColour(bytes, "m.colour");
  EXPECT_EQ(back.components, m.components);
  EXPECT_EQ(back.bins, m.bins);
  EXPECT_EQ(back.sessions, m.sessions);
  EXPECT_EQ(back.observations, m.observations);
  EXPECT_EQ(back.resolution_m, m.resolution_m);
  EXPECT_EQ(back.from_s, m.from_s);
  EXPECT_EQ(back.to_s, m.to_s);
  EXPECT_EQ(back.rms_error, m.rms_error);
  EXPECT_EQ(back.fitted_on.times_s, m.fitted_on.times_s);
  EXPECT_EQ(back.fitted_on.fingerprint, m.fitted_on.fingerprint);
  ASSERT_EQ(back.keys.size(), m.keys.size());
  for (size_t v = 0; v < m.keys.size(); ++v) {
    EXPECT_EQ(back.keys[v], m.keys[v]);
    for (double h : {0.0, 6.5, 13.0, 23.9}) EXPECT_EQ(back.predict(v, h), m.predict(v, h)) << v << " " << h;
  }
  EXPECT_EQ(back.predictMean(19.0), m.predictMean(19.0));
  const double t = kMonday_s + 86400.0 * 9 + 3600.0 * 19.0;
  const SessionMap snap = map.snapshot(times.back());
  const SessionMap a = recolour(snap, m, t), b = recolour(snap, back, t);
  for (int x = 0; x < 8; ++x) EXPECT_EQ(a.find(at(x, 2, 0))->meanColour(), b.find(at(x, 2, 0))->meanColour()) << x;
  EXPECT_EQ(serialize(back), bytes);

  // Every truncation, a wrong magic, a newer version and an unknown kind are refused, naming the file.
  for (size_t n = 0; n < bytes.size(); n += 5) {
    EXPECT_THROW(deserializeColour(std::span(bytes.data(), n), "m.colour"), FormatError) << n;
  }
  auto message = [](const std::vector<uint8_t>& input) {
    try {
      deserializeColour(input, "m.colour");
    } catch (const FormatError& e) {
      return std::string(e.what());
    }
    return std::string("read");
  };
  std::vector<uint8_t> bad = bytes;
  bad[0] = 'X';
  EXPECT_EQ(message(bad), "m.colour: not a chronomap colour model");
  bad = bytes;
  bad[4] = 3;
  EXPECT_EQ(message(bad), "m.colour: colour model version 3 (this build reads 1 to 2)");
  bad = bytes;
  bad[8] = 7;
  EXPECT_EQ(message(bad), "m.colour: colour model of unknown kind 7");
  bad = bytes;
  bad[9] = 9;  // nine light curves
  EXPECT_EQ(message(bad), "m.colour: bad header (9 light curves of 24 knots)");
  bad = bytes;
  bad.push_back(0);
  EXPECT_EQ(message(bad), "m.colour: bytes after the last voxel");
  EXPECT_EQ(message(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 60)),
            "m.colour: the colour model ends early (truncated)");
  // Random corruption either is refused or reads as a model that serialises back to those bytes.
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 500; ++trial) {
    std::vector<uint8_t> c = bytes;
    c[rng() % c.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
    try {
      EXPECT_EQ(serialize(deserializeColour(c, "c")), c);
    } catch (const FormatError&) {
    }
  }
}

TEST(Colour, BadInput) {
  // A map without colour changes.
  TemporalMap plain(0.05);
  SessionMap s(0.05);
  s.add(at(0, 0, 0), occupiedVoxel(Rgb{10, 20, 30}));
  plain.add(kMonday_s, s);
  EXPECT_THROW(fitColour(plain, kMonday_s, kMonday_s), UsageError);
  // A map with colour changes but no hits anywhere.
  TemporalMap empty(0.05, ChangeCriterion{0.0, 5.0});
  SessionMap f(0.05);
  f.add(at(0, 0, 0), test::freeVoxel());
  empty.add(kMonday_s, f);
  empty.add(kMonday_s + 3600, f);
  EXPECT_THROW(fitColour(empty, kMonday_s, kMonday_s + 3600), DataError);
  std::vector<double> times;
  TemporalMap map = wallMap(2, {9.0, 18.0}, 100, times);
  // No session in the range; NaN range.
  EXPECT_THROW(fitColour(map, times.back() + 1, times.back() + 2), UsageError);
  EXPECT_THROW(fitColour(map, std::nan(""), times.back()), UsageError);
  const ColourModel m = fitColour(map, times.front(), times.back());
  // Times: before the first session, NaN.
  ColourDiffSettings ds;
  ds.lighting_invariant = true;
  EXPECT_THROW(colourChanges(map, times.front() - 10, times.back(), &m, ds), UsageError);
  EXPECT_THROW(colourChanges(map, std::nan(""), times.back(), &m, ds), UsageError);
  EXPECT_THROW(colourChanges(map, times.front(), times.back(), nullptr, ds), UsageError);
  ds.distance = std::nan("");
  EXPECT_THROW(colourChanges(map, times.front(), times.back(), &m, ds), UsageError);
  EXPECT_THROW(recolour(map.snapshot(times.back()), m, std::numeric_limits<double>::infinity()), UsageError);
  // Observations: NaN colour, hour out of range, voxel out of range, none; bad settings.
  std::vector<ColourObservation> obs{{0, 12.0, {std::nan(""), 1, 1}}};
  EXPECT_THROW(fitColourObservations(obs, 1, {}), DataError);
  obs[0] = {0, 24.0, {1, 1, 1}};
  EXPECT_THROW(fitColourObservations(obs, 1, {}), DataError);
  obs[0] = {3, 12.0, {1, 1, 1}};
  EXPECT_THROW(fitColourObservations(obs, 1, {}), DataError);
  EXPECT_THROW(fitColourObservations({}, 1, {}), DataError);
  ColourSettings bad;
  bad.components = 4;
  obs[0] = {0, 12.0, {1, 1, 1}};
  EXPECT_THROW(fitColourObservations(obs, 1, bad), UsageError);
  bad = {};
  bad.bins = 1;
  EXPECT_THROW(fitColourObservations(obs, 1, bad), UsageError);
  bad = {};
  bad.smoothness = std::nan("");
  EXPECT_THROW(fitColourObservations(obs, 1, bad), UsageError);
}

TEST(Colour, HourOfDay) {
  EXPECT_DOUBLE_EQ(hourOfDay(kMonday_s + 3600.0 * 19.5), 19.5);
  EXPECT_DOUBLE_EQ(hourOfDay(kMonday_s), 0.0);
  EXPECT_DOUBLE_EQ(hourOfDay(-3600.0), 23.0);
  EXPECT_LT(hourOfDay(kMonday_s - 1e-7), 24.0);
}

}  // namespace
}  // namespace chronomap
