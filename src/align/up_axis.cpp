#include "chronomap/align/up_axis.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_set>
#include <vector>

#include "chronomap/core/error.h"

namespace chronomap {

const char* toString(UpAxis axis) {
  switch (axis) {
    case UpAxis::PlusX: return "+x";
    case UpAxis::MinusX: return "-x";
    case UpAxis::PlusY: return "+y";
    case UpAxis::MinusY: return "-y";
    case UpAxis::PlusZ: return "+z";
    case UpAxis::MinusZ: return "-z";
  }
  return "?";
}

UpAxis parseUpAxis(const std::string& name) {
  for (UpAxis a : kUpAxes) {
    if (name == toString(a) || (name.size() == 1 && name[0] == toString(a)[1] && toString(a)[0] == '+')) return a;
  }
  throw UsageError("up axis must be +x, -x, +y, -y, +z or -z, not '" + name + "'");
}

Eigen::Vector3d upVector(UpAxis axis) {
  const auto i = static_cast<int>(axis);
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  v[i / 2] = i % 2 == 0 ? 1.0 : -1.0;
  return v;
}

Eigen::Matrix3d uprightRotation(UpAxis axis) {
  Eigen::Matrix3d r;
  switch (axis) {
    case UpAxis::PlusZ: r.setIdentity(); break;
    case UpAxis::MinusZ: r << 1, 0, 0, 0, -1, 0, 0, 0, -1; break;  // half turn about x
    case UpAxis::PlusY: r << 1, 0, 0, 0, 0, -1, 0, 1, 0; break;    // quarter turn about x
    case UpAxis::MinusY: r << 1, 0, 0, 0, 0, 1, 0, -1, 0; break;   // the other way: z becomes +y
    case UpAxis::PlusX: r << 0, 0, -1, 0, 1, 0, 1, 0, 0; break;    // quarter turn about y
    case UpAxis::MinusX: r << 0, 0, 1, 0, 1, 0, -1, 0, 0; break;
  }
  return r;
}

namespace {

/// The upright cue of an axis the sensors' up does not point along: a floor there must be four
/// times the one the sensors stand upright on to win (a depth camera looking steeply down at a
/// table sees the far edge as a plane below it too).
constexpr double kUprightFloor = 0.25;

/// The sampled points of a recording in its world frame, each with the direction of its ray.
struct UpSample {
  std::vector<Eigen::Vector3d> points, rays;
  std::vector<Eigen::Vector3d> sensors, sensor_ups;  ///< of each frame read
};

UpSample sampleFrames(const FrameSource& frames, const UpEstimateSettings& s) {
  UpSample out;
  const size_t n = frames.size();
  const size_t picks = std::min(n, std::max<size_t>(s.max_frames, 1));
  const size_t per_frame = std::max<size_t>(s.max_points / std::max<size_t>(picks, 1), 1);
  std::unordered_set<uint64_t> cells;
  for (size_t k = 0; k < picks; ++k) {
    const size_t i = picks == 1 ? 0 : k * (n - 1) / (picks - 1);
    const Frame f = frames.load(i);
    const Eigen::Vector3d origin = f.T_world_sensor.translation();
    out.sensors.push_back(origin);
    out.sensor_ups.push_back(f.T_world_sensor.linear() * s.sensor_up);
    const size_t stride = std::max<size_t>(f.cloud.size() / per_frame, 1);
    for (size_t p = 0; p < f.cloud.size(); p += stride) {
      const Eigen::Vector3d local = f.cloud.points[p].cast<double>();
      const double range = local.norm();
      if (!std::isfinite(range) || range <= 0.0 || range > s.max_range_m) continue;
      const Eigen::Vector3d world = f.T_world_sensor * local;
      // One point per cell: surfaces count by their area, not by how close to the sensor they are
      // (a desk at 1 m gets 25 times the pixels of the same area of floor at 5 m).
      const Eigen::Vector3d cell = (world / s.bin_m).array().floor();
      uint64_t key = 0;
      for (int a = 0; a < 3; ++a) key = key << 21 | (static_cast<uint64_t>(static_cast<int64_t>(cell[a])) & 0x1fffff);
      if (!cells.insert(key).second) continue;
      out.points.push_back(world);
      out.rays.push_back(f.T_world_sensor.linear() * (local / range));
    }
  }
  return out;
}

/// The floor cue of one axis: the share of points in the densest slab at least clearance_m below
/// every sensor, and the share beneath that slab.
std::pair<double, double> floorShare(const UpSample& sample, const Eigen::Vector3d& u, const UpEstimateSettings& s) {
  double lowest_sensor = std::numeric_limits<double>::infinity();
  for (const auto& c : sample.sensors) lowest_sensor = std::min(lowest_sensor, c.dot(u));
  const double top = lowest_sensor - s.clearance_m;
  double bottom = top;
  for (const auto& p : sample.points) bottom = std::min(bottom, p.dot(u));
  const auto bins = static_cast<size_t>(std::floor((top - bottom) / s.bin_m)) + 1;
  std::vector<size_t> count(bins, 0);
  for (const auto& p : sample.points) {
    const double h = p.dot(u);
    if (h <= top) ++count[std::min(bins - 1, static_cast<size_t>((h - bottom) / s.bin_m))];
  }
  // The slab with the most points less the points beneath it: the floor, rather than a table top
  // that holds more points than the floor seen around it but has the floor beneath. A slab must
  // hold 1.5 times the points of the slab one slab above the next (a plane across u, not a ramp:
  // the far edge of a table seen steeply from above has nothing beneath it either; the slab in
  // between is skipped, where a floor seen slightly tilted or noisy still spreads).
  const auto slab = static_cast<size_t>(std::max(s.slab_bins, 1));
  std::vector<size_t> below(bins + 1, 0);  // points in the bins before each
  for (size_t b = 0; b < bins; ++b) below[b + 1] = below[b] + count[b];
  auto window = [&](size_t first) {
    return below[std::min(bins, first + slab)] - below[std::min(bins, first)];
  };
  size_t best = 0, best_beneath = 0;
  double best_margin = 0.0;
  for (size_t b = 0; b < bins; ++b) {
    const size_t in_window = window(b);
    if (2 * in_window < 3 * window(b + 2 * slab)) continue;
    const double margin = static_cast<double>(in_window) - static_cast<double>(below[b]);
    if (margin > best_margin) {
      best_margin = margin;
      best = in_window;
      best_beneath = below[b];
    }
  }
  const auto total = static_cast<double>(sample.points.size());
  return {static_cast<double>(best) / total, static_cast<double>(best_beneath) / total};
}

/// The standard deviation of the sensor positions along each axis.
Eigen::Vector3d pathSpread(const std::vector<Eigen::Vector3d>& sensors) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), square = Eigen::Vector3d::Zero();
  for (const auto& c : sensors) mean += c;
  mean /= static_cast<double>(sensors.size());
  for (const auto& c : sensors) square += (c - mean).cwiseAbs2();
  return (square / static_cast<double>(sensors.size())).cwiseSqrt();
}

}  // namespace

UpEstimate estimateUpAxis(const FrameSource& frames, const UpEstimateSettings& settings) {
  if (!(settings.bin_m > 0.0) || !(settings.max_range_m > 0.0)) {
    throw UsageError("up estimate: the bin and the range must be positive");
  }
  const UpSample sample = sampleFrames(frames, settings);
  UpEstimate out;
  out.frames = sample.sensors.size();
  out.points = sample.points.size();
  if (sample.points.empty()) {
    throw DataError("no valid point within " + std::to_string(settings.max_range_m) + " m in " +
                    std::to_string(out.frames) + " frame(s) to find the floor from; give the up axis (--up)");
  }
  // How far the rays run along each axis (either way): a sensor that turns about the up looks
  // along the horizontal axes, never far along the up.
  Eigen::Vector3d mean_ray = Eigen::Vector3d::Zero(), mean_up = Eigen::Vector3d::Zero();
  for (const auto& r : sample.rays) mean_ray += r.cwiseAbs();
  for (const auto& u : sample.sensor_ups) mean_up += u;
  mean_ray /= static_cast<double>(sample.rays.size());
  mean_up /= static_cast<double>(sample.sensor_ups.size());
  const Eigen::Vector3d spread = pathSpread(sample.sensors);
  double best = -1.0;
  for (size_t k = 0; k < kUpAxes.size(); ++k) {
    const Eigen::Vector3d u = upVector(kUpAxes[k]);
    const auto [share, beneath] = floorShare(sample, u, settings);
    const double across = 1.0 - mean_ray.dot(u.cwiseAbs());
    const double upright = kUprightFloor + (1.0 - kUprightFloor) * std::max(0.0, mean_up.dot(u));
    const double level = spread.sum() < settings.bin_m ? 1.0 : 1.0 - spread.dot(u.cwiseAbs()) / spread.sum();
    out.floor_share[k] = share;
    out.scores[k] = std::max(0.0, share - beneath) * across * upright * level;
    if (out.scores[k] > best) {
      best = out.scores[k];
      out.axis = kUpAxes[k];
    }
  }
  out.found = best >= settings.min_score;
  if (!out.found) {
    // No floor: the sensors' own up, when they agree on an axis; else the frame as recorded.
    out.axis = UpAxis::PlusZ;
    for (UpAxis a : kUpAxes) {
      if (mean_up.dot(upVector(a)) >= settings.min_sensor_agreement) out.axis = a;
    }
  }
  return out;
}

}  // namespace chronomap
