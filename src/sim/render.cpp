// The camera renderer: ray casting a scene state into Kinect-like RGB-D frames.
#include "chronomap/sim/render.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "internal.h"

namespace chronomap::sim {

using detail::Rng;

Camera kinectCamera(double scale) {
  Camera c;
  c.width = static_cast<uint32_t>(std::lround(640 * scale));
  c.height = static_cast<uint32_t>(std::lround(480 * scale));
  c.fx = c.fy = (c.width / 2.0) / std::tan(28.5 * std::numbers::pi / 180.0);
  c.cx = (c.width - 1) / 2.0;
  c.cy = (c.height - 1) / 2.0;
  return c;
}

Eigen::Vector3d lightingAt(double hour) {
  // Warm light in the morning and evening, neutral at noon, a little blue in the afternoon.
  const double h = std::fmod(std::max(hour, 0.0), 24.0);
  const double warm = std::exp(-std::pow((h - 8.0) / 2.5, 2)) + std::exp(-std::pow((h - 19.0) / 2.0, 2));
  const double cool = std::exp(-std::pow((h - 15.0) / 2.5, 2));
  return Eigen::Vector3d(1.0 + 0.12 * warm - 0.05 * cool, 1.0 + 0.02 * warm, 1.0 - 0.18 * warm + 0.08 * cool);
}

Renderer::Renderer(const SceneState& state) {
  for (const Object& o : state.objects) {
    if (!o.present) continue;
    parts_.insert(parts_.end(), o.parts.begin(), o.parts.end());
  }
  nodes_.reserve(2 * parts_.size() + 1);
  nodes_.push_back({});
  if (!parts_.empty()) build(0, 0, static_cast<uint32_t>(parts_.size()));
}

void Renderer::build(uint32_t node, uint32_t begin, uint32_t end) {
  Eigen::AlignedBox3d box, centers;
  for (uint32_t i = begin; i < end; ++i) {
    box.extend(parts_[i].box);
    centers.extend(parts_[i].box.center());
  }
  nodes_[node].box = box;
  if (end - begin <= 4) {
    nodes_[node].first = begin;
    nodes_[node].count = end - begin;
    return;
  }
  int axis = 0;
  centers.sizes().maxCoeff(&axis);
  const uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(parts_.begin() + begin, parts_.begin() + mid, parts_.begin() + end,
                   [axis](const Part& a, const Part& b) { return a.box.center()[axis] < b.box.center()[axis]; });
  const auto left = static_cast<uint32_t>(nodes_.size());
  nodes_.push_back({});
  nodes_.push_back({});
  nodes_[node].first = left;
  nodes_[node].count = 0;
  build(left, begin, mid);
  build(left + 1, mid, end);
}

namespace {

// Slab test: entry distance and the face it enters through, or false.
bool slab(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& o, const Eigen::Vector3d& inv, double t_max,
          double& t_enter, int& face) {
  double t0 = 0.0, t1 = t_max;
  face = -1;
  for (int a = 0; a < 3; ++a) {
    double tn = (box.min()[a] - o[a]) * inv[a];
    double tf = (box.max()[a] - o[a]) * inv[a];
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

}  // namespace

bool Renderer::cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double& t, Rgb& color) const {
  if (parts_.empty()) return false;
  const Eigen::Vector3d inv(1.0 / dir.x(), 1.0 / dir.y(), 1.0 / dir.z());
  double best = 1e30;
  int best_face = -1;
  const Part* best_part = nullptr;
  uint32_t stack[64];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    double te = 0.0;
    int face = 0;
    if (!slab(n.box, origin, inv, best, te, face)) continue;
    if (n.count == 0) {
      stack[top++] = n.first;
      stack[top++] = n.first + 1;
      continue;
    }
    for (uint32_t i = n.first; i < n.first + n.count; ++i) {
      if (slab(parts_[i].box, origin, inv, best, te, face) && face >= 0 && te < best) {
        best = te;
        best_face = face;
        best_part = &parts_[i];
      }
    }
  }
  if (!best_part) return false;
  t = best;
  color = best_part->face_colors[static_cast<size_t>(best_face)];
  return true;
}

RenderedFrame Renderer::render(const Camera& cam, const Eigen::Isometry3d& T, const SensorModel& sensor, double hour,
                               uint64_t seed) const {
  RenderedFrame f;
  const size_t n = size_t{cam.width} * cam.height;
  f.rgb.width = f.depth.width = cam.width;
  f.rgb.height = f.depth.height = cam.height;
  f.rgb.pixels.assign(n, Rgb{});
  f.depth.pixels.assign(n, 0);
  f.true_depth_m.assign(n, 0.0f);
  std::vector<uint8_t> dark(n, 0);
  const Eigen::Vector3d light = lightingAt(hour);
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d o = T.translation();
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      const Eigen::Vector3d d_cam((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
      const double norm = d_cam.norm();
      const Eigen::Vector3d d = R * (d_cam / norm);
      double t = 0.0;
      Rgb c;
      if (!cast(o, d, t, c)) continue;
      const size_t i = size_t{v} * cam.width + u;
      const double z = t / norm;
      f.true_depth_m[i] = static_cast<float>(z);
      // A faint checker texture on every surface so that colour varies along it.
      const Eigen::Vector3d p = o + t * d;
      const bool checker = (static_cast<int64_t>(std::floor(p.x() / 0.25)) + static_cast<int64_t>(std::floor(p.y() / 0.25)) +
                            static_cast<int64_t>(std::floor(p.z() / 0.25))) % 2 != 0;
      const double tex = checker ? 0.93 : 1.0;
      dark[i] = 0.299 * c.r + 0.587 * c.g + 0.114 * c.b < sensor.dark_luminance;
      auto ch = [&](uint8_t base, double l) {
        return static_cast<uint8_t>(std::clamp(std::lround(base * tex * l), 0L, 255L));
      };
      f.rgb.pixels[i] = Rgb{ch(c.r, light.x()), ch(c.g, light.y()), ch(c.b, light.z())};
    }
  }
  Rng rng(seed);
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      const size_t i = size_t{v} * cam.width + u;
      const double z = f.true_depth_m[i];
      const double noise = rng.normal();
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
      const double measured = z + sensor.noise_per_m2 * z * z * noise;
      const double units = std::round(measured * sensor.depth_scale);
      if (units >= 1.0 && units <= 65535.0) f.depth.pixels[i] = static_cast<uint16_t>(units);
    }
  }
  return f;
}

}  // namespace chronomap::sim
