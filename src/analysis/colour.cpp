#include "chronomap/analysis/colour.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <string>

#include <Eigen/Dense>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"

namespace chronomap {

namespace {

/// Knots and weights of the piecewise linear, circular curve at `hour`.
struct Knots {
  int i0 = 0, i1 = 0;
  double w0 = 1.0, w1 = 0.0;
};

Knots knotsAt(double hour, int bins) {
  double h = std::fmod(hour, 24.0);
  if (h < 0.0) h += 24.0;
  const double x = h * bins / 24.0;
  const double fl = std::floor(x);
  Knots k;
  k.i0 = static_cast<int>(fl) % bins;
  k.i1 = (k.i0 + 1) % bins;
  k.w1 = x - fl;
  k.w0 = 1.0 - k.w1;
  return k;
}

/// Observations grouped by voxel: order[start[v] .. start[v + 1]) index `obs`.
struct ByVoxel {
  std::vector<size_t> start, order;
};

ByVoxel groupByVoxel(std::span<const ColourObservation> obs, size_t voxels) {
  ByVoxel g;
  g.start.assign(voxels + 1, 0);
  for (const ColourObservation& o : obs) ++g.start[o.voxel + 1];
  for (size_t v = 0; v < voxels; ++v) g.start[v + 1] += g.start[v];
  g.order.resize(obs.size());
  std::vector<size_t> fill(g.start.begin(), g.start.end() - 1);
  for (size_t k = 0; k < obs.size(); ++k) g.order[fill[obs[k].voxel]++] = k;
  return g;
}

/// Solves the weights of one voxel given the curves (all three channels).
void solveWeights(const ColourModel& m, std::span<const ColourObservation> obs, const ByVoxel& g, size_t v,
                  float* weights) {
  const int K = m.components;
  for (int c = 0; c < 3; ++c) {
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(K, K);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(K);
    for (size_t k = g.start[v]; k < g.start[v + 1]; ++k) {
      const ColourObservation& o = obs[g.order[k]];
      Eigen::VectorXd x(K);
      for (int j = 0; j < K; ++j) x(j) = m.curve(j, c, o.hour);
      G += x * x.transpose();
      b += x * o.rgb[static_cast<size_t>(c)];
    }
    // A small ridge keeps a voxel seen at few hours (or at hours where the curves agree) solvable.
    const double ridge = 1e-6 * (G.trace() / K) + 1e-9;
    G.diagonal().array() += ridge;
    const Eigen::VectorXd a = G.ldlt().solve(b);
    for (int j = 0; j < K; ++j) weights[j * 3 + c] = static_cast<float>(a(j));
  }
}

/// Solves the curves given the weights of the voxels in `subset`.
void solveCurves(ColourModel& m, std::span<const ColourObservation> obs, const ByVoxel& g,
                 const std::vector<size_t>& subset, const std::vector<float>& weights, double smoothness) {
  const int K = m.components, B = m.bins, n = K * B;
  for (int c = 0; c < 3; ++c) {
    Eigen::MatrixXd N = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    for (size_t s = 0; s < subset.size(); ++s) {
      const size_t v = subset[s];
      const float* a = weights.data() + s * static_cast<size_t>(K) * 3;
      for (size_t k = g.start[v]; k < g.start[v + 1]; ++k) {
        const ColourObservation& o = obs[g.order[k]];
        const Knots kn = knotsAt(o.hour, B);
        int idx[6];
        double val[6];
        int m_entries = 0;
        for (int j = 0; j < K; ++j) {
          idx[m_entries] = j * B + kn.i0;
          val[m_entries++] = a[j * 3 + c] * kn.w0;
          idx[m_entries] = j * B + kn.i1;
          val[m_entries++] = a[j * 3 + c] * kn.w1;
        }
        for (int p = 0; p < m_entries; ++p) {
          rhs(idx[p]) += val[p] * o.rgb[static_cast<size_t>(c)];
          for (int q = 0; q < m_entries; ++q) N(idx[p], idx[q]) += val[p] * val[q];
        }
      }
    }
    // Smoothness between neighbouring knots, scaled by the observations per knot and by the
    // weights' size so that its strength does not depend on how many voxels or how bright.
    const double scale = std::max(N.trace() / n, 1e-12);
    const double lambda = smoothness * scale;
    for (int j = 0; j < K; ++j) {
      for (int i = 0; i < B; ++i) {
        const int p = j * B + i, q = j * B + (i + 1) % B;
        N(p, p) += lambda;
        N(q, q) += lambda;
        N(p, q) -= lambda;
        N(q, p) -= lambda;
      }
    }
    N.diagonal().array() += 1e-9 * scale;
    const Eigen::VectorXd theta = N.ldlt().solve(rhs);
    for (int p = 0; p < n; ++p) m.curves[static_cast<size_t>((p / B * 3 + c) * B + p % B)] = theta(p);
  }
}

/// Scales each curve to a largest magnitude of 1 (positive), the weights by the inverse.
void normalise(ColourModel& m, std::vector<float>& weights, size_t voxels) {
  const int K = m.components, B = m.bins;
  for (int j = 0; j < K; ++j) {
    for (int c = 0; c < 3; ++c) {
      double* L = m.curves.data() + static_cast<size_t>((j * 3 + c) * B);
      double peak = 0.0;
      for (int i = 0; i < B; ++i) {
        if (std::abs(L[i]) > std::abs(peak)) peak = L[i];
      }
      if (std::abs(peak) < 1e-12) continue;
      for (int i = 0; i < B; ++i) L[i] /= peak;
      for (size_t v = 0; v < voxels; ++v) {
        weights[(v * static_cast<size_t>(K) + static_cast<size_t>(j)) * 3 + static_cast<size_t>(c)] *=
            static_cast<float>(peak);
      }
    }
  }
}

}  // namespace

void ColourSettings::validate() const {
  if (components < 1 || components > 3) throw UsageError("colour model: components must be 1, 2 or 3");
  if (bins < 2 || bins > 96) throw UsageError("colour model: bins must lie between 2 and 96");
  if (iterations < 1 || iterations > 10000) throw UsageError("colour model: iterations must lie between 1 and 10000");
  if (!std::isfinite(smoothness) || smoothness < 0.0) throw UsageError("colour model: smoothness must be >= 0");
  if (max_fit_voxels < 1) throw UsageError("colour model: max_fit_voxels must be at least 1");
}

double ColourModel::curve(int j, int c, double hour) const {
  const Knots k = knotsAt(hour, bins);
  const double* L = curves.data() + static_cast<size_t>((j * 3 + c) * bins);
  return k.w0 * L[k.i0] + k.w1 * L[k.i1];
}

std::array<double, 3> ColourModel::predict(size_t v, double hour) const {
  std::array<double, 3> out{};
  for (int c = 0; c < 3; ++c) {
    for (int j = 0; j < components; ++j) {
      out[static_cast<size_t>(c)] +=
          weights[(v * static_cast<size_t>(components) + static_cast<size_t>(j)) * 3 + static_cast<size_t>(c)] *
          curve(j, c, hour);
    }
  }
  return out;
}

std::array<double, 3> ColourModel::predictMean(double hour) const {
  std::array<double, 3> out{};
  if (keys.empty()) return out;
  for (int c = 0; c < 3; ++c) {
    for (int j = 0; j < components; ++j) {
      double mean = 0.0;
      for (size_t v = 0; v < keys.size(); ++v) {
        mean += weights[(v * static_cast<size_t>(components) + static_cast<size_t>(j)) * 3 + static_cast<size_t>(c)];
      }
      out[static_cast<size_t>(c)] += mean / static_cast<double>(keys.size()) * curve(j, c, hour);
    }
  }
  return out;
}

std::optional<size_t> ColourModel::find(const VoxelKey& key) const {
  const uint64_t code = mortonEncode(key);
  const auto it = std::lower_bound(keys.begin(), keys.end(), code,
                                   [](const VoxelKey& k, uint64_t c) { return mortonEncode(k) < c; });
  if (it == keys.end() || !(*it == key)) return std::nullopt;
  return static_cast<size_t>(it - keys.begin());
}

ColourModel fitColourObservations(std::span<const ColourObservation> obs, size_t voxels,
                                  const ColourSettings& settings) {
  settings.validate();
  if (obs.empty() || voxels == 0) throw DataError("colour model: no colour observation to learn from");
  for (const ColourObservation& o : obs) {
    if (o.voxel >= voxels) throw DataError("colour model: an observation names voxel " + std::to_string(o.voxel) +
                                           " of " + std::to_string(voxels));
    if (!std::isfinite(o.hour) || o.hour < 0.0 || o.hour >= 24.0) {
      throw DataError("colour model: an observation's hour is not in [0, 24)");
    }
    for (double x : o.rgb) {
      if (!std::isfinite(x) || x < 0.0 || x > 255.0) throw DataError("colour model: a colour is not in 0..255");
    }
  }
  ColourModel m;
  m.components = settings.components;
  m.bins = settings.bins;
  m.observations = obs.size();
  const int K = m.components, B = m.bins;
  m.curves.assign(static_cast<size_t>(K * 3 * B), 0.0);
  // Start: a constant light, then daily waves of other phases for the other components.
  for (int j = 0; j < K; ++j) {
    for (int c = 0; c < 3; ++c) {
      for (int i = 0; i < B; ++i) {
        m.curves[static_cast<size_t>((j * 3 + c) * B + i)] =
            j == 0 ? 1.0 : 0.5 + 0.5 * std::cos(2.0 * std::numbers::pi * i / B - std::numbers::pi * j / K);
      }
    }
  }
  const ByVoxel g = groupByVoxel(obs, voxels);
  // The curves are fitted on a subset of the voxels with observations, evenly spread.
  std::vector<size_t> with_obs;
  for (size_t v = 0; v < voxels; ++v) {
    if (g.start[v + 1] > g.start[v]) with_obs.push_back(v);
  }
  std::vector<size_t> subset;
  const size_t stride = (with_obs.size() + settings.max_fit_voxels - 1) / settings.max_fit_voxels;
  for (size_t k = 0; k < with_obs.size(); k += std::max<size_t>(stride, 1)) subset.push_back(with_obs[k]);
  std::vector<float> w(subset.size() * static_cast<size_t>(K) * 3, 0.0f);
  for (int it = 0; it < settings.iterations; ++it) {
    for (size_t s = 0; s < subset.size(); ++s) solveWeights(m, obs, g, subset[s], w.data() + s * static_cast<size_t>(K) * 3);
    solveCurves(m, obs, g, subset, w, settings.smoothness);
    normalise(m, w, subset.size());
  }
  // Every voxel's weights under the final curves.
  m.weights.assign(voxels * static_cast<size_t>(K) * 3, 0.0f);
  double sq = 0.0;
  for (size_t v = 0; v < voxels; ++v) {
    solveWeights(m, obs, g, v, m.weights.data() + v * static_cast<size_t>(K) * 3);
    for (size_t k = g.start[v]; k < g.start[v + 1]; ++k) {
      const ColourObservation& o = obs[g.order[k]];
      const std::array<double, 3> p = m.predict(v, o.hour);
      for (size_t c = 0; c < 3; ++c) sq += (p[c] - o.rgb[c]) * (p[c] - o.rgb[c]);
    }
  }
  m.rms_error = std::sqrt(sq / (3.0 * static_cast<double>(obs.size())));
  return m;
}

ColourData colourObservations(const TemporalMap& map, double from_s, double to_s, size_t min_observations) {
  if (!(map.criterion().colour_distance > 0.0)) {
    throw UsageError("the 4D map keeps no colour changes (it was created without --color-distance), so it holds "
                     "each surface's colour at one hour only; build it with --color-distance D");
  }
  if (std::isnan(from_s) || std::isnan(to_s)) throw UsageError("colour model: the learning range is not a number");
  const std::vector<double> times = map.times();
  const uint32_t first = static_cast<uint32_t>(std::lower_bound(times.begin(), times.end(), from_s) - times.begin());
  const uint32_t end = static_cast<uint32_t>(std::upper_bound(times.begin(), times.end(), to_s) - times.begin());
  if (first >= end) throw UsageError("colour model: no session to learn from in the range");
  ColourData d;
  d.sessions = end - first;
  d.from_s = times[first];
  d.to_s = times[end - 1];
  std::vector<CoverageIndex> coverage;
  coverage.reserve(end - first);
  std::vector<double> hours;
  for (uint32_t r = first; r < end; ++r) {
    coverage.emplace_back(map.sessions()[r].coverage);
    hours.push_back(hourOfDay(times[r]));
  }
  std::vector<ColourObservation> mine;
  map.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
    if (level != 0) return;
    mine.clear();
    size_t e = 0;
    for (uint32_t r = first; r < end; ++r) {
      while (e + 1 < entries.size() && entries[e + 1].session <= r) ++e;
      if (entries[e].session > r) continue;
      const VoxelCounters& v = entries[e].value;
      if (v.hits == 0 || v.state() != VoxelState::Occupied) continue;
      if (!coverage[r - first].contains(corner)) continue;
      const double n = static_cast<double>(v.hits);
      ColourObservation o;
      o.voxel = static_cast<uint32_t>(d.keys.size());
      o.hour = hours[r - first];
      o.rgb = {v.red / n, v.green / n, v.blue / n};
      mine.push_back(o);
    }
    if (mine.size() < std::max<size_t>(min_observations, 1)) return;
    d.keys.push_back(corner);
    d.observations.insert(d.observations.end(), mine.begin(), mine.end());
  });
  if (d.keys.empty()) throw DataError("colour model: no voxel of the map holds colour in the learning range");
  // forEachList walks the tree depth first, which is Morton order; sort to be sure.
  std::vector<size_t> order(d.keys.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  if (!std::is_sorted(d.keys.begin(), d.keys.end(),
                      [](const VoxelKey& a, const VoxelKey& b) { return mortonEncode(a) < mortonEncode(b); })) {
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return mortonEncode(d.keys[a]) < mortonEncode(d.keys[b]); });
    std::vector<uint32_t> rank(order.size());
    for (size_t k = 0; k < order.size(); ++k) rank[order[k]] = static_cast<uint32_t>(k);
    std::vector<VoxelKey> keys(order.size());
    for (size_t k = 0; k < order.size(); ++k) keys[k] = d.keys[order[k]];
    d.keys = std::move(keys);
    for (ColourObservation& o : d.observations) o.voxel = rank[o.voxel];
  }
  return d;
}

ColourModel fitColour(const TemporalMap& map, double from_s, double to_s, const ColourSettings& settings) {
  settings.validate();
  ColourData d = colourObservations(map, from_s, to_s);
  ColourModel m = fitColourObservations(d.observations, d.keys.size(), settings);
  m.keys = std::move(d.keys);
  m.sessions = d.sessions;
  m.from_s = d.from_s;
  m.to_s = d.to_s;
  m.resolution_m = map.resolution_m();
  m.fitted_on = fittedOn(map, m.from_s, m.to_s);
  return m;
}

SessionMap recolour(const SessionMap& map, const ColourModel& model, double time_s) {
  if (!std::isfinite(time_s)) throw UsageError("colour prediction: the time is not finite");
  const double hour = hourOfDay(time_s);
  SessionMap out = map;
  std::vector<std::pair<VoxelKey, VoxelCounters>> changed;
  map.forEachLeaf([&](const LeafView& leaf) {
    if (leaf.level != 0 || leaf.counters.hits == 0) return;
    const auto v = model.find(leaf.key);
    if (!v) return;
    const std::array<double, 3> p = model.predict(*v, hour);
    VoxelCounters c = leaf.counters;
    const double n = static_cast<double>(c.hits);
    auto sum = [&](double x) { return static_cast<uint32_t>(std::lround(std::clamp(x, 0.0, 255.0) * n)); };
    c.red = sum(p[0]);
    c.green = sum(p[1]);
    c.blue = sum(p[2]);
    changed.emplace_back(leaf.key, c);
  });
  for (const auto& [key, c] : changed) out.assign(key, c);
  return out;
}

void ColourDiffSettings::validate() const {
  if (!std::isfinite(distance) || distance <= 0.0) throw UsageError("the colour distance must be a positive number");
}

std::pair<double, Rgb> lightingDistance(const Rgb& before, const Rgb& after, const std::array<double, 3>& gain,
                                        double uncertainty) {
  const double b[3] = {double(before.r), double(before.g), double(before.b)};
  const double a[3] = {double(after.r), double(after.g), double(after.b)};
  const double mean_gain = (gain[0] + gain[1] + gain[2]) / 3.0;
  double sq = 0.0, scale = 0.0;
  double e[3];
  for (size_t c = 0; c < 3; ++c) e[c] = std::clamp(b[c] * gain[c], 0.0, 255.0);
  if (mean_gain >= 1.0) {
    // The second hour is brighter: the first colour scaled up (its uncertainty too).
    for (size_t c = 0; c < 3; ++c) {
      sq += (a[c] - e[c]) * (a[c] - e[c]);
      scale = std::max(scale, gain[c]);
    }
  } else {
    // The first hour is brighter: the second colour scaled up to it.
    for (size_t c = 0; c < 3; ++c) {
      const double inv = gain[c] > 1e-6 ? 1.0 / gain[c] : 1e6;
      const double up = std::clamp(a[c] * inv, 0.0, 255.0);
      sq += (b[c] - up) * (b[c] - up);
      scale = std::max(scale, inv);
    }
  }
  const Rgb expected{static_cast<uint8_t>(std::lround(e[0])), static_cast<uint8_t>(std::lround(e[1])),
                     static_cast<uint8_t>(std::lround(e[2]))};
  return {std::max(0.0, std::sqrt(sq) - uncertainty * (1.0 + scale)), expected};
}

ColourDiff colourChanges(const TemporalMap& map, double t1_s, double t2_s, const ColourModel* model,
                         const ColourDiffSettings& settings) {
  settings.validate();
  if (!std::isfinite(t1_s) || !std::isfinite(t2_s)) throw UsageError("colour diff: a time is not finite");
  if (settings.lighting_invariant && (model == nullptr || model->keys.empty())) {
    throw UsageError("a lighting-invariant colour diff needs a colour model of the map");
  }
  const auto r1 = map.rankAtOrBefore(t1_s), r2 = map.rankAtOrBefore(t2_s);
  if (!r1 || !r2) throw UsageError("colour diff: a time lies before the map's first session");
  // A stored colour lags the observed one by up to the map's colour distance, plus rounding.
  const double uncertainty = map.criterion().colour_distance + 0.87;
  // Each voxel's colour at a time is the one its last observation up to then left (the entry
  // valid then, within the map's colour distance), seen at that observation's hour: a voxel no
  // session observed between the two times has nothing new to compare.
  const std::vector<double> times = map.times();
  const uint32_t last = std::max(*r1, *r2);
  std::vector<CoverageIndex> coverage;
  coverage.reserve(last + 1);
  for (uint32_t r = 0; r <= last; ++r) coverage.emplace_back(map.sessions()[r].coverage);
  const auto lastObserver = [&](const VoxelKey& key, uint32_t r) -> std::optional<uint32_t> {
    for (int64_t q = r; q >= 0; --q) {
      if (coverage[static_cast<size_t>(q)].contains(key)) return static_cast<uint32_t>(q);
    }
    return std::nullopt;
  };
  ColourDiff out;
  const auto at = [](std::span<const TemporalMap::Entry> entries, uint32_t r) -> const TemporalMap::Entry* {
    const TemporalMap::Entry* found = nullptr;
    for (const TemporalMap::Entry& e : entries) {
      if (e.session > r) break;
      found = &e;
    }
    return found;
  };
  map.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
    if (level != 0) return;
    const TemporalMap::Entry* e1 = at(entries, *r1);
    const TemporalMap::Entry* e2 = at(entries, *r2);
    if (!e1 || !e2) return;
    const VoxelCounters &a = e1->value, &b = e2->value;
    if (a.hits == 0 || b.hits == 0 || a.state() != VoxelState::Occupied || b.state() != VoxelState::Occupied) return;
    const auto o1 = lastObserver(corner, *r1), o2 = lastObserver(corner, *r2);
    if (!o1 || !o2 || *o1 == *o2) return;
    ++out.compared;
    ColourChange ch;
    ch.key = corner;
    ch.before = a.meanColour();
    ch.after = b.meanColour();
    double dist = 0.0;
    if (settings.lighting_invariant) {
      const double h1 = hourOfDay(times[*o1]), h2 = hourOfDay(times[*o2]);
      std::array<double, 3> gain{1.0, 1.0, 1.0};
      const auto v = model->find(corner);
      const std::array<double, 3> p1 = v ? model->predict(*v, h1) : model->predictMean(h1);
      const std::array<double, 3> p2 = v ? model->predict(*v, h2) : model->predictMean(h2);
      for (size_t c = 0; c < 3; ++c) {
        if (p1[c] > 0.5 && p2[c] > 0.0) gain[c] = std::clamp(p2[c] / p1[c], 0.0, 100.0);
      }
      const auto [d, expected] = lightingDistance(ch.before, ch.after, gain, uncertainty);
      dist = d;
      ch.expected = expected;
    } else {
      const double dr = double(ch.after.r) - ch.before.r, dg = double(ch.after.g) - ch.before.g,
                   db = double(ch.after.b) - ch.before.b;
      dist = std::sqrt(dr * dr + dg * dg + db * db);
      ch.expected = ch.before;
    }
    if (dist <= settings.distance) return;
    ch.distance = static_cast<float>(dist);
    out.changes.push_back(ch);
  });
  return out;
}

}  // namespace chronomap
