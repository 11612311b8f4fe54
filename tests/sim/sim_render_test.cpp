// The simulator's renderer against two slow references: every part tested for every ray (no
// hierarchy), and the first renderer (a median-split hierarchy walked in a fixed order, kept
// here as it was) whose images the fast one must reproduce bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "chronomap/sim/render.h"
#include "chronomap/sim/scene.h"
#include "builders.h"

namespace chronomap {
namespace {

struct Hit {
  bool hit = false;
  double t = 0.0;
  Rgb colour{};
};

bool sameHit(const Hit& a, const Hit& b) {
  return a.hit == b.hit && (!a.hit || (a.t == b.t && a.colour.r == b.colour.r && a.colour.g == b.colour.g &&
                                        a.colour.b == b.colour.b));
}

// The slab test as the renderer has always done it: entry distance and entry face.
bool slab(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& o, const Eigen::Vector3d& inv, double t_max,
          double& t_enter, int& face) {
  double t0 = 0.0, t1 = t_max;
  face = -1;
  for (int a = 0; a < 3; ++a) {
    double tn = (box.min()[a] - o[a]) * inv[a];
    double tf = (box.max()[a] - o[a]) * inv[a];
    int fn = 2 * a;
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

// Every part tested, nearest first, ties to the earlier part of the list.
Hit bruteForce(const std::vector<Part>& parts, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const Eigen::Vector3d inv(1.0 / d.x(), 1.0 / d.y(), 1.0 / d.z());
  Hit h;
  double best = 1e30;
  for (const Part& p : parts) {
    double te = 0.0;
    int face = 0;
    if (slab(p.box, o, inv, best, te, face) && face >= 0 && te < best) {
      best = te;
      h = {true, te, p.face_colours[static_cast<size_t>(face)]};
    }
  }
  return h;
}

// The first renderer's hierarchy and walk, unchanged.
class LegacyRenderer {
 public:
  explicit LegacyRenderer(const SceneState& state) {
    for (const Object& o : state.objects) {
      if (o.present) parts_.insert(parts_.end(), o.parts.begin(), o.parts.end());
    }
    nodes_.push_back({});
    if (!parts_.empty()) build(0, 0, static_cast<uint32_t>(parts_.size()));
  }
  Hit cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const {
    Hit h;
    if (parts_.empty()) return h;
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
    if (best_part) h = {true, best, best_part->face_colours[static_cast<size_t>(best_face)]};
    return h;
  }

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    uint32_t first = 0, count = 0;
  };
  std::vector<Part> parts_;
  std::vector<Node> nodes_;
  void build(uint32_t node, uint32_t begin, uint32_t end) {
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
};

Hit fast(const Renderer& r, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  Hit h;
  h.hit = r.cast(o, d, h.t, h.colour);
  return h;
}

// A scene of boxes on a 0.5 m lattice with sizes in whole lattice steps, many touching,
// overlapping or sharing faces with others of other colours: rays meet equally near parts often.
SceneState latticeScene(uint64_t seed, int boxes) {
  std::mt19937_64 rng(seed);
  auto step = [&](int lo, int hi) { return 0.5 * std::uniform_int_distribution<int>(lo, hi)(rng); };
  SceneState s;
  for (int i = 0; i < boxes; ++i) {
    Object o;
    o.id = static_cast<uint32_t>(i);
    Part p;
    const Eigen::Vector3d lo(step(0, 16), step(0, 16), step(0, 6));
    const Eigen::Vector3d size(step(1, 4), step(1, 4), step(1, 3));
    p.box = Eigen::AlignedBox3d(lo, lo + size);
    for (size_t f = 0; f < 6; ++f) {
      p.face_colours[f] = Rgb{static_cast<uint8_t>(i), static_cast<uint8_t>(f * 40), static_cast<uint8_t>(i * 7)};
    }
    o.parts.push_back(p);
    o.present = i % 11 != 5;  // some absent: the renderer must leave them out
    s.objects.push_back(o);
  }
  return s;
}

// Rays from random origins in `box` in random directions, and a few axis-aligned ones.
void compareOnRays(const SceneState& scene, const Eigen::AlignedBox3d& box, int rays, uint64_t seed,
                   size_t* ties = nullptr) {
  const Renderer renderer(scene);
  const LegacyRenderer legacy(scene);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  size_t hits = 0;
  for (int i = 0; i < rays; ++i) {
    Eigen::Vector3d o;
    for (int a = 0; a < 3; ++a) o[a] = box.min()[a] + u(rng) * box.sizes()[a];
    Eigen::Vector3d d(g(rng), g(rng), g(rng));
    if (i % 50 == 0) d = Eigen::Vector3d::Unit(i / 50 % 3) * (i % 100 == 0 ? 1.0 : -1.0);
    if (i % 7 == 0) o = o.array().round();  // origins on lattice planes
    d.normalize();
    const Hit want = bruteForce(renderer.parts(), o, d);
    const Hit got = fast(renderer, o, d);
    const Hit old = legacy.cast(o, d);
    ASSERT_TRUE(sameHit(got, want)) << "ray " << i << " from " << o.transpose() << " along " << d.transpose()
                                    << ": fast " << got.hit << " t " << got.t << ", every part " << want.hit << " t "
                                    << want.t;
    ASSERT_TRUE(sameHit(got, old)) << "ray " << i << " from " << o.transpose() << " along " << d.transpose();
    hits += want.hit;
    if (ties && want.hit) {
      // Count rays on which another part is exactly as near (the tie-breaking order matters).
      const Eigen::Vector3d inv(1.0 / d.x(), 1.0 / d.y(), 1.0 / d.z());
      int same = 0;
      for (const Part& p : renderer.parts()) {
        double te = 0.0;
        int face = 0;
        if (slab(p.box, o, inv, 1e30, te, face) && face >= 0 && te == want.t) ++same;
      }
      *ties += same > 1;
    }
  }
  EXPECT_GT(hits, static_cast<size_t>(rays) / 4);
}

TEST(Renderer, NearestHitEqualsEveryPartTestedAndTheFirstRenderer) {
  for (const char* preset : {"tiny", "office", "floor66", "weeks", "site"}) {
    SCOPED_TRACE(preset);
    const SceneState scene = makeScene(preset, 5);
    compareOnRays(scene, scene.bounds, 3000, 11);
  }
}

TEST(Renderer, EquallyNearPartsGoToTheEarlierOneAsBefore) {
  for (uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(seed);
    size_t ties = 0;
    const SceneState scene = latticeScene(seed, 120);
    compareOnRays(scene, Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(10, 10, 5)), 4000, seed,
                  &ties);
    EXPECT_GT(ties, 20u) << "the lattice should make rays meet equally near parts";
  }
}

TEST(Renderer, TwoPartsInTheSamePlaceShowTheEarlierOne) {
  // Two identical boxes of different colours (and filler boxes so that the hierarchy is deep):
  // every ray that meets them meets both at the same distance; the colour is that of the part
  // that comes first in parts(), and the first renderer showed the same.
  SceneState s = latticeScene(9, 40);
  for (uint8_t c : {uint8_t{200}, uint8_t{100}}) {
    Object o;
    Part p;
    p.box = Eigen::AlignedBox3d(Eigen::Vector3d(20, 0, 0), Eigen::Vector3d(21, 1, 1));
    p.face_colours.fill(Rgb{c, c, c});
    o.parts.push_back(p);
    s.objects.push_back(o);
  }
  const Renderer renderer(s);
  const LegacyRenderer legacy(s);
  uint8_t first = 0;
  for (const Part& p : renderer.parts()) {
    if (p.box.min().x() == 20.0) {
      first = p.face_colours[0].r;
      break;
    }
  }
  ASSERT_NE(first, 0);
  for (double y : {0.1, 0.5, 0.9}) {
    const Eigen::Vector3d o(25, y, 0.5), d(-1, 0, 0);
    const Hit h = fast(renderer, o, d);
    ASSERT_TRUE(h.hit);
    EXPECT_EQ(h.t, 4.0);
    EXPECT_EQ(h.colour.r, first);
    EXPECT_TRUE(sameHit(h, legacy.cast(o, d)));
  }
}

TEST(Renderer, FramesEqualThoseOfEveryPartTested) {
  // Whole frames: render()'s depth (noise-free) and colour against the same pixels cast by
  // testing every part, with render()'s ray directions, texture and lighting.
  for (const char* preset : {"office", "floor66", "site"}) {
    SCOPED_TRACE(preset);
    const SceneState scene = makeScene(preset, 2);
    const bool site = std::string(preset) == "site";  // views on every floor, the floors above in sight
    const Renderer renderer(scene);
    const Camera cam = kinectCamera(0.25);
    const SensorModel sensor;
    const double hour = 17.5;
    const Eigen::Vector3d light = lightingAt(hour);
    const Eigen::Vector3d c = scene.bounds.center();
    size_t hits = 0;
    // Views along the building, looking down, level and up, one from inside a part.
    const int views = 5;
    for (int view = 0; view < views; ++view) {
      Eigen::Vector3d at(c.x() + 0.7 * view, c.y() - 0.3, 1.2 + (site ? kSiteFloorHeight_m * (view % kSiteFloors) : 0.0));
      if (view == views - 1) at = renderer.parts()[renderer.parts().size() / 2].box.center();
      const Eigen::Isometry3d T = test::cameraLooking(at, 1.3 * view + 0.2, view % 3 == 0 ? -0.2 : (view % 3 == 1 ? -0.9 : 0.5));
      const RenderedFrame f = renderer.render(cam, T, sensor, hour, 7 + view);
      const Eigen::Matrix3d R = T.rotation();
      for (uint32_t v = 0; v < cam.height; ++v) {
        for (uint32_t u = 0; u < cam.width; ++u) {
          const Eigen::Vector3d d_cam((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
          const double norm = d_cam.norm();
          const Eigen::Vector3d d = R * (d_cam / norm);
          const Hit want = bruteForce(renderer.parts(), T.translation(), d);
          const size_t i = size_t{v} * cam.width + u;
          if (!want.hit) {
            ASSERT_EQ(f.true_depth_m[i], 0.0f);
            continue;
          }
          ++hits;
          ASSERT_EQ(f.true_depth_m[i], static_cast<float>(want.t / norm)) << "pixel " << u << ", " << v;
          const Eigen::Vector3d p = T.translation() + want.t * d;
          const bool checker = (static_cast<int64_t>(std::floor(p.x() / 0.25)) +
                                static_cast<int64_t>(std::floor(p.y() / 0.25)) +
                                static_cast<int64_t>(std::floor(p.z() / 0.25))) % 2 != 0;
          const double tex = checker ? 0.93 : 1.0;
          auto ch = [&](uint8_t base, double l) {
            return static_cast<uint8_t>(std::clamp(std::lround(base * tex * l), 0L, 255L));
          };
          ASSERT_EQ(f.rgb.pixels[i].r, ch(want.colour.r, light.x()));
          ASSERT_EQ(f.rgb.pixels[i].g, ch(want.colour.g, light.y()));
          ASSERT_EQ(f.rgb.pixels[i].b, ch(want.colour.b, light.z()));
        }
      }
    }
    EXPECT_GT(hits, size_t{views} * cam.width * cam.height / 2);
  }
}

TEST(Renderer, AnEmptySceneHitsNothing) {
  SceneState s = latticeScene(4, 3);
  for (auto& o : s.objects) o.present = false;
  const Renderer renderer(s);
  EXPECT_TRUE(renderer.parts().empty());
  EXPECT_FALSE(fast(renderer, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0)).hit);
}

}  // namespace
}  // namespace chronomap
