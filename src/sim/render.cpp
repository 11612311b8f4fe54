// The camera renderer: ray casting a scene state into Kinect-like RGB-D frames.
#include "chronomap/sim/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "chronomap/core/error.h"
#include "internal.h"

namespace chronomap {

using sim_detail::Rng;

Camera kinectCamera(double scale) {
  Camera c;
  c.width = static_cast<uint32_t>(std::lround(640 * scale));
  c.height = static_cast<uint32_t>(std::lround(480 * scale));
  c.fx = c.fy = (c.width / 2.0) / std::tan(28.5 * std::numbers::pi / 180.0);
  c.cx = (c.width - 1) / 2.0;
  c.cy = (c.height - 1) / 2.0;
  return c;
}

const char* toString(SensorKind kind) {
  switch (kind) {
    case SensorKind::Ideal: return "ideal";
    case SensorKind::Kinect: return "kinect";
    case SensorKind::RealSense: return "realsense";
  }
  return "ideal";
}

SensorKind parseSensorKind(const std::string& name) {
  for (const SensorKind k : {SensorKind::Ideal, SensorKind::Kinect, SensorKind::RealSense}) {
    if (name == toString(k)) return k;
  }
  throw UsageError("--sensor must be ideal, kinect or realsense, not '" + name + "'");
}

SensorModel sensorModel(SensorKind kind) {
  SensorModel s;
  s.kind = kind;
  if (kind == SensorKind::Kinect) {
    // DepthCameraModel's defaults are the Kinect's (Nguyen, Izadi and Lovell 2012; a 7.5 cm
    // baseline, 580 px focal length and 1/8 px disparity steps).
    s.min_range_m = 0.5;
    s.max_range_m = 4.5;
  } else if (kind == SensorKind::RealSense) {
    // D435-like: Intel's RMS error z^2 * 0.08 px / (focal * baseline) with a 5 cm baseline and
    // 447 px (848 px wide at 87 degrees), 1/32 px disparity steps, a little more lost on dark
    // and shiny surfaces and at slightly less grazing incidence (active stereo).
    DepthCameraModel& c = s.camera;
    c.axial_a_m = 0.001;
    c.axial_b_per_m = 0.0036;
    c.axial_z0_m = 0.0;
    c.baseline_m = 0.05;
    c.focal_px = 447.0;
    c.disparity_step_px = 1.0 / 32.0;
    c.max_incidence_deg = 75.0;
    c.dark_dropout = 0.6;
    c.dark_bias_m = 0.02;
    c.shiny_dropout = 0.5;
    c.shiny_bias_m = 0.03;
    s.min_range_m = 0.3;
    s.max_range_m = 6.0;
  }
  return s;
}

double axialSigma(const DepthCameraModel& c, double z, double theta) {
  const double grazing = theta / std::max(std::numbers::pi / 2 - theta, 1e-3);
  return c.axial_a_m + c.axial_b_per_m * (z - c.axial_z0_m) * (z - c.axial_z0_m) +
         c.axial_incidence_m / std::sqrt(std::max(z, 1e-3)) * grazing * grazing;
}

double depthStep(const DepthCameraModel& c, double z) {
  if (!(c.disparity_step_px > 0.0)) return 0.0;
  return z * z * c.disparity_step_px / (c.baseline_m * c.focal_px);
}

Eigen::Vector3d lightingAt(double hour) {
  // Warm light in the morning and evening, neutral at noon, a little blue in the afternoon.
  const double h = std::fmod(std::max(hour, 0.0), 24.0);
  const double warm = std::exp(-std::pow((h - 8.0) / 2.5, 2)) + std::exp(-std::pow((h - 19.0) / 2.0, 2));
  const double cool = std::exp(-std::pow((h - 15.0) / 2.5, 2));
  return Eigen::Vector3d(1.0 + 0.12 * warm - 0.05 * cool, 1.0 + 0.02 * warm, 1.0 - 0.18 * warm + 0.08 * cool);
}

namespace {

double smoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

double hourOfDay(double hour) {
  const double h = std::fmod(hour, 24.0);
  return h < 0.0 ? h + 24.0 : h;
}

}  // namespace

Eigen::Vector3d Daylight::ceiling(double hour) {
  const double h = hourOfDay(hour);
  const double on = smoothStep((h - 6.75) / 0.5) * (1.0 - smoothStep((h - 18.75) / 0.5));
  return Eigen::Vector3d(0.06, 0.06, 0.07) + on * Eigen::Vector3d(0.50, 0.49, 0.44);
}

Eigen::Vector3d Daylight::daylight(double hour) {
  const double h = hourOfDay(hour);
  if (h <= 6.5 || h >= 19.0) return Eigen::Vector3d::Zero();
  const double e = std::sin(std::numbers::pi * (h - 6.5) / 12.5);  // the sun's height, 0..1
  const double strength = 0.75 * std::pow(e, 0.6);
  return strength * Eigen::Vector3d(1.0, 0.70 + 0.30 * e, 0.40 + 0.60 * e);
}

double Daylight::window(const Eigen::Vector3d& p) const {
  const double d = std::max(0.0, std::min({p.x() - building.min().x(), building.max().x() - p.x(),
                                           p.y() - building.min().y(), building.max().y() - p.y()}));
  return std::exp(-d / 2.0);
}

namespace {

// The order in which the first renderer met the parts: a hierarchy split at the median of the
// part centres along their longest extent down to 4 parts per leaf, walked depth first, second
// child first. Ties between equally near parts went to the one met first, so this order keeps
// every image as that renderer drew it.
void legacyOrder(std::vector<Part>& parts, uint32_t begin, uint32_t end, std::vector<Part>& out) {
  if (end - begin <= 4) {
    out.insert(out.end(), parts.begin() + begin, parts.begin() + end);
    return;
  }
  Eigen::AlignedBox3d centers;
  for (uint32_t i = begin; i < end; ++i) centers.extend(parts[i].box.center());
  int axis = 0;
  centers.sizes().maxCoeff(&axis);
  const uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(parts.begin() + begin, parts.begin() + mid, parts.begin() + end,
                   [axis](const Part& a, const Part& b) { return a.box.center()[axis] < b.box.center()[axis]; });
  legacyOrder(parts, mid, end, out);
  legacyOrder(parts, begin, mid, out);
}

constexpr int kBins = 16;
constexpr uint32_t kMaxLeaf = 4;
constexpr int kMedianDepth = 64;
constexpr int kStack = kMedianDepth + 40;  // the median splits below add at most 32 levels

double halfArea(const double lo[3], const double hi[3]) {
  const double x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
  return x * y + y * z + z * x;
}

}  // namespace

Renderer::Renderer(const SceneState& state) {
  std::vector<Part> present;
  for (const Object& o : state.objects) {
    if (!o.present) continue;
    present.insert(present.end(), o.parts.begin(), o.parts.end());
  }
  parts_.reserve(present.size());
  legacyOrder(present, 0, static_cast<uint32_t>(present.size()), parts_);
  std::vector<Box> boxes(parts_.size());
  for (size_t i = 0; i < parts_.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      boxes[i].lo[a] = parts_[i].box.min()[a];
      boxes[i].hi[a] = parts_[i].box.max()[a];
    }
    boxes[i].part = static_cast<uint32_t>(i);
  }
  nodes_.reserve(2 * boxes.size() + 1);
  nodes_.push_back({});
  if (!boxes.empty()) build(boxes, 0, 0, static_cast<uint32_t>(boxes.size()), 0);
  boxes_ = std::move(boxes);
}

// Fills node `index` over boxes [begin, end): a binned surface-area-heuristic split, children
// adjacent; below depth kMedianDepth the split is at the median centre, which bounds the depth.
void Renderer::build(std::vector<Box>& boxes, uint32_t index, uint32_t begin, uint32_t end, int depth) {
  Node n;
  double clo[3], chi[3];
  for (int a = 0; a < 3; ++a) {
    n.lo[a] = clo[a] = std::numeric_limits<double>::max();
    n.hi[a] = chi[a] = std::numeric_limits<double>::lowest();
  }
  for (uint32_t i = begin; i < end; ++i) {
    for (int a = 0; a < 3; ++a) {
      n.lo[a] = std::min(n.lo[a], boxes[i].lo[a]);
      n.hi[a] = std::max(n.hi[a], boxes[i].hi[a]);
      const double c = 0.5 * (boxes[i].lo[a] + boxes[i].hi[a]);
      clo[a] = std::min(clo[a], c);
      chi[a] = std::max(chi[a], c);
    }
  }
  const uint32_t count = end - begin;
  // The cheapest split over kBins bins of the centres along each axis: cost of a leaf is one
  // box test per part, of a split one node test plus the parts weighted by the children's areas.
  double best_cost = std::numeric_limits<double>::max();
  int best_axis = -1, best_bin = 0;
  const double area = std::max(halfArea(n.lo, n.hi), 1e-30);
  for (int a = 0; a < 3 && count > 1 && depth < kMedianDepth; ++a) {
    const double extent = chi[a] - clo[a];
    if (!(extent > 0.0)) continue;
    struct Bin {
      double lo[3], hi[3];
      uint32_t count = 0;
    } bins[kBins];
    for (Bin& b : bins) {
      for (int k = 0; k < 3; ++k) {
        b.lo[k] = std::numeric_limits<double>::max();
        b.hi[k] = std::numeric_limits<double>::lowest();
      }
    }
    const double scale = kBins / extent;
    for (uint32_t i = begin; i < end; ++i) {
      const double c = 0.5 * (boxes[i].lo[a] + boxes[i].hi[a]);
      const int k = std::min(kBins - 1, static_cast<int>((c - clo[a]) * scale));
      Bin& b = bins[k];
      ++b.count;
      for (int j = 0; j < 3; ++j) {
        b.lo[j] = std::min(b.lo[j], boxes[i].lo[j]);
        b.hi[j] = std::max(b.hi[j], boxes[i].hi[j]);
      }
    }
    // Sweep from the right, then from the left.
    double right_cost[kBins];
    Bin acc;
    for (int k = 0; k < 3; ++k) {
      acc.lo[k] = std::numeric_limits<double>::max();
      acc.hi[k] = std::numeric_limits<double>::lowest();
    }
    for (int k = kBins - 1; k > 0; --k) {
      acc.count += bins[k].count;
      for (int j = 0; j < 3; ++j) {
        acc.lo[j] = std::min(acc.lo[j], bins[k].lo[j]);
        acc.hi[j] = std::max(acc.hi[j], bins[k].hi[j]);
      }
      right_cost[k] = acc.count ? acc.count * halfArea(acc.lo, acc.hi) : 0.0;
    }
    Bin left;
    for (int k = 0; k < 3; ++k) {
      left.lo[k] = std::numeric_limits<double>::max();
      left.hi[k] = std::numeric_limits<double>::lowest();
    }
    for (int k = 0; k < kBins - 1; ++k) {
      left.count += bins[k].count;
      for (int j = 0; j < 3; ++j) {
        left.lo[j] = std::min(left.lo[j], bins[k].lo[j]);
        left.hi[j] = std::max(left.hi[j], bins[k].hi[j]);
      }
      if (left.count == 0 || left.count == count) continue;
      const double cost = 1.0 + (left.count * halfArea(left.lo, left.hi) + right_cost[k + 1]) / area;
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = a;
        best_bin = k;
      }
    }
  }
  if (count <= kMaxLeaf && (best_axis < 0 || best_cost >= static_cast<double>(count))) {
    n.first = begin;
    n.count = count;
    nodes_[index] = n;
    return;
  }
  uint32_t mid;
  if (best_axis >= 0) {
    const int a = best_axis;
    const double scale = kBins / (chi[a] - clo[a]);
    const double lo = clo[a];
    mid = static_cast<uint32_t>(
        std::partition(boxes.begin() + begin, boxes.begin() + end,
                       [&](const Box& b) {
                         return std::min(kBins - 1, static_cast<int>((0.5 * (b.lo[a] + b.hi[a]) - lo) * scale)) <=
                                best_bin;
                       }) -
        boxes.begin());
  } else {  // too deep, or every centre in one place: halve the list along the widest spread
    int a = 0;
    double widest = -1.0;
    for (int k = 0; k < 3; ++k) {
      if (chi[k] - clo[k] > widest) {
        widest = chi[k] - clo[k];
        a = k;
      }
    }
    mid = begin + count / 2;
    std::nth_element(boxes.begin() + begin, boxes.begin() + mid, boxes.begin() + end,
                     [a](const Box& x, const Box& y) { return x.lo[a] + x.hi[a] < y.lo[a] + y.hi[a]; });
  }
  const auto left = static_cast<uint32_t>(nodes_.size());
  n.first = left;
  n.count = 0;
  nodes_[index] = n;
  nodes_.push_back({});
  nodes_.push_back({});
  build(boxes, left, begin, mid, depth + 1);
  build(boxes, left + 1, mid, end, depth + 1);
}

namespace {

// Slab test: entry distance and the face it enters through, or false.
bool slab(const double lo[3], const double hi[3], const Eigen::Vector3d& o, const Eigen::Vector3d& inv, double t_max,
          double& t_enter, int& face) {
  double t0 = 0.0, t1 = t_max;
  face = -1;
  for (int a = 0; a < 3; ++a) {
    double tn = (lo[a] - o[a]) * inv[a];
    double tf = (hi[a] - o[a]) * inv[a];
    int fn = 2 * a;  // entering through the min face
    if (tn > tf) {
      std::swap(tn, tf);
      fn = 2 * a + 1;
    }
    if (tn > t0) {
      t0 = tn;
      face = fn;
    }
    t1 = std::min(t1, tf);
    if (t0 > t1) return false;
  }
  t_enter = t0;
  return true;
}

/// The nearest part a ray has hit so far: its distance, the face it entered through and its
/// index. At equal distances the lower index wins, the order the renderer always kept.
struct NearestHit {
  double t = 1e30;
  int face = -1;
  uint32_t part = std::numeric_limits<uint32_t>::max();

  void consider(const double lo[3], const double hi[3], uint32_t p, const Eigen::Vector3d& o,
                const Eigen::Vector3d& inv) {
    double te = 0.0;
    int f = 0;
    if (slab(lo, hi, o, inv, t, te, f) && f >= 0 && (te < t || (te == t && p < part))) {
      t = te;
      face = f;
      part = p;
    }
  }
};

}  // namespace

bool Renderer::cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double& t, Rgb& colour) const {
  if (parts_.empty()) return false;
  const Eigen::Vector3d inv(1.0 / dir.x(), 1.0 / dir.y(), 1.0 / dir.z());
  // Nodes are tested with the near and far planes picked by the ray's direction.
  const double ox = origin.x(), oy = origin.y(), oz = origin.z();
  const double ix = inv.x(), iy = inv.y(), iz = inv.z();
  const bool nx = ix < 0.0, ny = iy < 0.0, nz = iz < 0.0;
  NearestHit hit;
  double te = 0.0;
  auto enter = [&](const Node& n, double& t_node) {
    const double x0 = ((nx ? n.hi[0] : n.lo[0]) - ox) * ix, x1 = ((nx ? n.lo[0] : n.hi[0]) - ox) * ix;
    const double y0 = ((ny ? n.hi[1] : n.lo[1]) - oy) * iy, y1 = ((ny ? n.lo[1] : n.hi[1]) - oy) * iy;
    const double z0 = ((nz ? n.hi[2] : n.lo[2]) - oz) * iz, z1 = ((nz ? n.lo[2] : n.hi[2]) - oz) * iz;
    double t0 = 0.0, t1 = hit.t;
    t0 = x0 > t0 ? x0 : t0;
    t0 = y0 > t0 ? y0 : t0;
    t0 = z0 > t0 ? z0 : t0;
    t1 = x1 < t1 ? x1 : t1;
    t1 = y1 < t1 ? y1 : t1;
    t1 = z1 < t1 ? z1 : t1;
    t_node = t0;
    return t0 <= t1;
  };
  // Near child first; a node farther than the nearest hit so far is skipped (an equally far one
  // is not: it may hold a part that wins the tie).
  struct Entry {
    uint32_t node;
    double t;
  } stack[kStack];
  int top = 0;
  if (!enter(nodes_[0], te)) return false;
  stack[top++] = {0, te};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.t > hit.t) continue;
    const Node& n = nodes_[e.node];
    if (n.count == 0) {
      double ta = 0.0, tb = 0.0;
      const bool ha = enter(nodes_[n.first], ta), hb = enter(nodes_[n.first + 1], tb);
      if (ha && hb) {
        if (ta <= tb) {
          stack[top++] = {n.first + 1, tb};
          stack[top++] = {n.first, ta};
        } else {
          stack[top++] = {n.first, ta};
          stack[top++] = {n.first + 1, tb};
        }
      } else if (ha) {
        stack[top++] = {n.first, ta};
      } else if (hb) {
        stack[top++] = {n.first + 1, tb};
      }
      continue;
    }
    for (uint32_t i = n.first; i < n.first + n.count; ++i) hit.consider(boxes_[i].lo, boxes_[i].hi, boxes_[i].part, origin, inv);
  }
  if (hit.face < 0) return false;
  t = hit.t;
  colour = parts_[hit.part].face_colours[static_cast<size_t>(hit.face)];
  return true;
}

namespace {

// The parts each tile of a frame can see. Every ray of a frame starts at the camera, so a part
// can only be hit by the pixels that its box projects onto: each part goes into the list of
// every 16 x 16 tile its projection (padded by a pixel) covers, or of every tile when part of
// the box lies behind the camera. The lists are sorted by the distance from the camera to the
// box, a lower bound of where any ray meets it, so that a pixel stops at the first part farther
// than its nearest hit. A pixel's answer is that of every part tested: the nearest, and at equal
// distance the earlier in parts().
class Tiles {
 public:
  static constexpr uint32_t kSize = 16;

  Tiles(const std::vector<Part>& parts, const Camera& cam, const Eigen::Matrix3d& R, const Eigen::Vector3d& o)
      : across_((cam.width + kSize - 1) / kSize), down_((cam.height + kSize - 1) / kSize) {
    struct Seen {
      double near;
      uint32_t part, u0, u1, v0, v1;  // tiles [u0, u1] x [v0, v1]
    };
    std::vector<Seen> seen;
    seen.reserve(parts.size());
    const Eigen::Matrix3d Rt = R.transpose();
    for (uint32_t i = 0; i < parts.size(); ++i) {
      const Eigen::AlignedBox3d& b = parts[i].box;
      const Eigen::Vector3d outside = (b.min() - o).cwiseMax(o - b.max()).cwiseMax(0.0);
      Seen s{outside.norm(), i, 0, across_ - 1, 0, down_ - 1};
      double umin = std::numeric_limits<double>::max(), umax = std::numeric_limits<double>::lowest();
      double vmin = umin, vmax = umax;
      bool behind = false;
      for (int k = 0; k < 8; ++k) {
        const Eigen::Vector3d c = Rt * (b.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)) - o);
        if (c.z() <= 1e-6) {
          behind = true;
          break;
        }
        const double u = cam.fx * c.x() / c.z() + cam.cx, v = cam.fy * c.y() / c.z() + cam.cy;
        umin = std::min(umin, u);
        umax = std::max(umax, u);
        vmin = std::min(vmin, v);
        vmax = std::max(vmax, v);
      }
      if (!behind) {
        // Pixels [umin - 1, umax + 1] x [vmin - 1, vmax + 1], clipped to the image.
        if (umax + 1.0 < 0.0 || vmax + 1.0 < 0.0 || umin - 1.0 > cam.width - 1.0 || vmin - 1.0 > cam.height - 1.0) {
          continue;
        }
        auto tile = [](double p, uint32_t last) {
          return static_cast<uint32_t>(std::clamp(std::floor(p / kSize), 0.0, static_cast<double>(last)));
        };
        s.u0 = tile(umin - 1.0, across_ - 1);
        s.u1 = tile(umax + 1.0, across_ - 1);
        s.v0 = tile(vmin - 1.0, down_ - 1);
        s.v1 = tile(vmax + 1.0, down_ - 1);
      }
      // A little below the distance, so that rounding can never put it above a ray's entry.
      s.near = s.near * (1.0 - 1e-9) - 1e-9;
      seen.push_back(s);
    }
    std::sort(seen.begin(), seen.end(),
              [](const Seen& a, const Seen& b) { return a.near < b.near || (a.near == b.near && a.part < b.part); });
    start_.assign(size_t{across_} * down_ + 1, 0);
    for (const Seen& s : seen) {
      for (uint32_t tv = s.v0; tv <= s.v1; ++tv) {
        for (uint32_t tu = s.u0; tu <= s.u1; ++tu) ++start_[size_t{tv} * across_ + tu + 1];
      }
    }
    for (size_t k = 1; k < start_.size(); ++k) start_[k] += start_[k - 1];
    entries_.resize(start_.back());
    std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
    for (const Seen& s : seen) {
      const Box box{{parts[s.part].box.min().x(), parts[s.part].box.min().y(), parts[s.part].box.min().z()},
                    {parts[s.part].box.max().x(), parts[s.part].box.max().y(), parts[s.part].box.max().z()},
                    s.near,
                    s.part};
      for (uint32_t tv = s.v0; tv <= s.v1; ++tv) {
        for (uint32_t tu = s.u0; tu <= s.u1; ++tu) entries_[fill[size_t{tv} * across_ + tu]++] = box;
      }
    }
  }

  // The nearest part along the ray of pixel (u, v), from the camera at `o` along unit `dir`.
  bool cast(const std::vector<Part>& parts, uint32_t u, uint32_t v, const Eigen::Vector3d& o,
            const Eigen::Vector3d& dir, double& t, Rgb& colour, int& face, uint32_t& part) const {
    const Eigen::Vector3d inv(1.0 / dir.x(), 1.0 / dir.y(), 1.0 / dir.z());
    const size_t tile = size_t{v / kSize} * across_ + u / kSize;
    NearestHit hit;
    for (uint32_t k = start_[tile]; k < start_[tile + 1]; ++k) {
      const Box& b = entries_[k];
      if (b.near > hit.t) break;  // this part and all after it are farther than the hit
      hit.consider(b.lo, b.hi, b.part, o, inv);
    }
    if (hit.face < 0) return false;
    t = hit.t;
    colour = parts[hit.part].face_colours[static_cast<size_t>(hit.face)];
    face = hit.face;
    part = hit.part;
    return true;
  }

 private:
  struct Box {
    double lo[3], hi[3];
    double near;
    uint32_t part;
  };
  uint32_t across_, down_;
  std::vector<uint32_t> start_;  // tile k's parts: entries_[start_[k], start_[k + 1])
  std::vector<Box> entries_;
};

// What the first pass of render() found at each pixel that the depth camera model needs.
struct Surfaces {
  std::vector<uint8_t> dark;   // the albedo is darker than SensorModel::dark_luminance
  std::vector<uint8_t> shiny;  // the face hit is shiny (Part::shiny_faces)
  std::vector<float> theta;    // incidence: the angle between the ray and the face's normal (radians)
};

// A pixel at a depth edge: a 4-neighbour with no depth or one more than 5% nearer or farther
// (the ideal model's rule). `other` is the farthest such neighbour's depth (0: only missing ones).
bool depthEdge(const std::vector<float>& depth, const Camera& cam, uint32_t u, uint32_t v, double& other) {
  const double z = depth[size_t{v} * cam.width + u];
  bool edge = false;
  other = 0.0;
  double gap = 0.0;
  const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
  for (int k = 0; k < 4; ++k) {
    const int64_t uu = static_cast<int64_t>(u) + du[k], vv = static_cast<int64_t>(v) + dv[k];
    if (uu < 0 || vv < 0 || uu >= cam.width || vv >= cam.height) continue;
    const double zn = depth[static_cast<size_t>(vv) * cam.width + static_cast<size_t>(uu)];
    if (zn != 0.0 && std::abs(zn - z) <= 0.05 * z) continue;
    edge = true;
    if (zn != 0.0 && std::abs(zn - z) > gap) {
      gap = std::abs(zn - z);
      other = zn;
    }
  }
  return edge;
}

// The depth camera model (DepthCameraModel, in its order) over a frame whose true depth and
// surfaces are known. Eight draws per pixel whatever happens to it, so that each pixel's noise
// depends on the seed and its place only.
void depthCamera(RenderedFrame& f, const Surfaces& s, const Camera& cam, const SensorModel& sensor, uint64_t seed) {
  const DepthCameraModel& m = sensor.camera;
  const double max_theta = m.max_incidence_deg * std::numbers::pi / 180.0;
  const double fb = m.baseline_m * m.focal_px;
  Rng rng(seed);
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      double r[8];
      for (double& x : r) x = rng.uniform();
      const size_t i = size_t{v} * cam.width + u;
      // Lateral noise: the pixel samples the scene a rounded Gaussian offset away.
      const double grazing =
          f.true_depth_m[i] > 0.0f ? s.theta[i] / std::max(std::numbers::pi / 2 - s.theta[i], 1e-3) : 0.0;
      const double sigma_l = m.lateral_px + m.lateral_incidence_px * grazing;
      const double radius = std::sqrt(-2.0 * std::log(std::max(r[0], 1e-300)));
      auto offset = [&](double n, uint32_t at, uint32_t size) {
        const double d = std::clamp(std::round(sigma_l * n), -m.lateral_max_px, m.lateral_max_px);
        return static_cast<uint32_t>(std::clamp(static_cast<int64_t>(at) + static_cast<int64_t>(d), int64_t{0},
                                                static_cast<int64_t>(size) - 1));
      };
      const uint32_t us = offset(radius * std::cos(2.0 * std::numbers::pi * r[1]), u, cam.width);
      const uint32_t vs = offset(radius * std::sin(2.0 * std::numbers::pi * r[1]), v, cam.height);
      const size_t src = size_t{vs} * cam.width + us;
      double z = f.true_depth_m[src];
      if (z < sensor.min_range_m || z > sensor.max_range_m || s.theta[src] > max_theta) continue;
      double other = 0.0;
      if (depthEdge(f.true_depth_m, cam, us, vs, other)) {
        if (r[4] < m.edge_dropout) continue;
        if (r[4] < m.edge_dropout + m.flying_pixel) {
          if (other == 0.0) continue;
          z += (0.15 + 0.7 * r[5]) * (other - z);  // a flying pixel, between the two surfaces
        }
      }
      if (s.dark[src]) {
        if (r[6] < m.dark_dropout) continue;
        z += m.dark_bias_m;
      }
      if (s.shiny[src]) {
        if (r[7] < m.shiny_dropout) continue;
        z += m.shiny_bias_m;
      }
      // Axial noise: the published spread includes the quantisation's, so the Gaussian part is
      // what is left of it after the quantisation's step^2 / 12.
      const double sigma = axialSigma(m, z, s.theta[src]), step = depthStep(m, z);
      z += std::sqrt(std::max(sigma * sigma - step * step / 12.0, 0.0)) * Rng::normalOf(r[2], r[3]);
      if (step > 0.0 && z > 0.0) {
        const double disparity = std::round(fb / z / m.disparity_step_px) * m.disparity_step_px;
        if (!(disparity > 0.0)) continue;
        z = fb / disparity;
      }
      const double units = std::round(z * sensor.depth_scale);
      if (units >= 1.0 && units <= 65535.0) f.depth.pixels[i] = static_cast<uint16_t>(units);
    }
  }
}

}  // namespace

RenderedFrame Renderer::render(const Camera& cam, const Eigen::Isometry3d& T, const SensorModel& sensor, double hour,
                               uint64_t seed, const Daylight* daylight) const {
  RenderedFrame f;
  const size_t n = size_t{cam.width} * cam.height;
  f.rgb.width = f.depth.width = cam.width;
  f.rgb.height = f.depth.height = cam.height;
  f.rgb.pixels.assign(n, Rgb{});
  f.depth.pixels.assign(n, 0);
  f.true_depth_m.assign(n, 0.0f);
  Surfaces surfaces;
  std::vector<uint8_t>& dark = surfaces.dark;
  dark.assign(n, 0);
  const bool camera_model = sensor.kind != SensorKind::Ideal;
  if (camera_model) {
    surfaces.shiny.assign(n, 0);
    surfaces.theta.assign(n, 0.0f);
  }
  const Eigen::Vector3d light = lightingAt(hour);
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d o = T.translation();
  const Tiles tiles(parts_, cam, R, o);
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      const Eigen::Vector3d d_cam((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
      const double norm = d_cam.norm();
      const Eigen::Vector3d d = R * (d_cam / norm);
      double t = 0.0;
      Rgb c;
      int face = 0;
      uint32_t part = 0;
      if (!tiles.cast(parts_, u, v, o, d, t, c, face, part)) continue;
      const size_t i = size_t{v} * cam.width + u;
      const double z = t / norm;
      f.true_depth_m[i] = static_cast<float>(z);
      if (camera_model) {
        surfaces.shiny[i] = (parts_[part].shiny_faces >> face) & 1u;
        surfaces.theta[i] = static_cast<float>(std::acos(std::min(1.0, std::abs(d[face / 2]))));
      }
      // A faint checker texture on every surface so that colour varies along it.
      const Eigen::Vector3d p = o + t * d;
      const bool checker = (static_cast<int64_t>(std::floor(p.x() / 0.25)) + static_cast<int64_t>(std::floor(p.y() / 0.25)) +
                            static_cast<int64_t>(std::floor(p.z() / 0.25))) % 2 != 0;
      const double tex = checker ? 0.93 : 1.0;
      dark[i] = 0.299 * c.r + 0.587 * c.g + 0.114 * c.b < sensor.dark_luminance;
      auto ch = [&](uint8_t base, double l) {
        return static_cast<uint8_t>(std::clamp(std::lround(base * tex * l), 0L, 255L));
      };
      const Eigen::Vector3d l = daylight ? daylight->at(hour, p) : light;
      f.rgb.pixels[i] = Rgb{ch(c.r, l.x()), ch(c.g, l.y()), ch(c.b, l.z())};
    }
  }
  if (camera_model) {
    depthCamera(f, surfaces, cam, sensor, seed);
    return f;
  }
  Rng rng(seed);
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      const size_t i = size_t{v} * cam.width + u;
      const double z = f.true_depth_m[i];
      // Three draws per pixel whatever happens to it; the noise is worked out only if needed.
      const double u1 = rng.uniform(), u2 = rng.uniform();
      const double drop = rng.uniform();
      if (z < sensor.min_range_m || z > sensor.max_range_m) continue;
      bool edge = false;
      const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
      for (int k = 0; k < 4; ++k) {
        const int64_t uu = static_cast<int64_t>(u) + du[k], vv = static_cast<int64_t>(v) + dv[k];
        if (uu < 0 || vv < 0 || uu >= cam.width || vv >= cam.height) continue;
        const double zn = f.true_depth_m[static_cast<size_t>(vv) * cam.width + static_cast<size_t>(uu)];
        if (zn == 0.0 || std::abs(zn - z) > 0.05 * z) edge = true;
      }
      if (edge && drop < sensor.edge_dropout) continue;
      if (dark[i] && drop < sensor.dark_dropout) continue;
      const double measured = z + sensor.noise_per_m2 * z * z * Rng::normalOf(u1, u2);
      const double units = std::round(measured * sensor.depth_scale);
      if (units >= 1.0 && units <= 65535.0) f.depth.pixels[i] = static_cast<uint16_t>(units);
    }
  }
  return f;
}

}  // namespace chronomap
