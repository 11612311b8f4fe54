#include "chronomap/sim/building.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>

#include "chronomap/core/error.h"
#include "chronomap/core/parallel.h"
#include "chronomap/core/time.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/file.h"
#include "chronomap/io/png.h"

namespace chronomap::sim {

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------------------------------------
// Randomness that is the same on every platform (std distributions are not).

struct Rng {
  uint64_t state;
  explicit Rng(uint64_t seed) : state(seed * 0x9e3779b97f4a7c15ULL + 0x632be59bd9b4e019ULL) {}
  uint64_t next() {  // SplitMix64
    uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  bool chance(double p) { return uniform() < p; }
  int below(int n) { return static_cast<int>(next() % static_cast<uint64_t>(n)); }
  double normal() {  // Box-Muller
    const double u1 = std::max(uniform(), 1e-300), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
};

uint64_t mix(uint64_t a, uint64_t b) { return Rng(a ^ (b * 0xd1342543de82ef95ULL)).next(); }

constexpr double kWallHeight = 2.5;
constexpr double kWallThickness = 0.1;
constexpr double kDoorWidth = 1.0;
constexpr double kDoorHeight = 2.1;
constexpr double kCameraHeight = 1.2;
constexpr double kCameraPitchDeg = -12.0;
constexpr double kClearRadius = 0.8;  // around the places the robot stands
// Shift of the whole building against the voxel grid, so that floors and walls do not lie on
// voxel faces (a real map frame has no reason to align with them).
const Eigen::Vector3d kOffset(0.013, 0.021, 0.017);

Rgb shade(Rgb c, double f) {
  auto s = [f](uint8_t v) { return static_cast<uint8_t>(std::clamp(std::lround(v * f), 0L, 255L)); };
  return {s(c.r), s(c.g), s(c.b)};
}

Part solid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Rgb c) {
  Part p;
  p.box = Eigen::AlignedBox3d(lo, hi);
  // Sides slightly darker than the top, as under ceiling light.
  p.face_colors = {shade(c, 0.85), shade(c, 0.9), shade(c, 0.8), shade(c, 0.95), shade(c, 0.6), c};
  return p;
}

Rgb randomColor(Rng& rng, int lo, int hi) {
  return {static_cast<uint8_t>(lo + rng.below(hi - lo)), static_cast<uint8_t>(lo + rng.below(hi - lo)),
          static_cast<uint8_t>(lo + rng.below(hi - lo))};
}

struct Builder {
  SceneState s;
  uint32_t next_id = 0;
  Object& add(ObjectKind kind, int room, std::vector<Part> parts) {
    Object o;
    o.id = next_id++;
    o.kind = kind;
    o.room = room;
    o.parts = std::move(parts);
    s.objects.push_back(std::move(o));
    return s.objects.back();
  }
};

// A chair whose back stands on its +y side (back_north) or its -y side.
std::vector<Part> chairAt(double x, double y, bool back_north, Rgb c) {
  std::vector<Part> p;
  p.push_back(solid({x - 0.22, y - 0.22, 0.0}, {x + 0.22, y + 0.22, 0.46}, c));  // seat on its base
  if (back_north) {
    p.push_back(solid({x - 0.22, y + 0.17, 0.46}, {x + 0.22, y + 0.22, 0.9}, c));
  } else {
    p.push_back(solid({x - 0.22, y - 0.22, 0.46}, {x + 0.22, y - 0.17, 0.9}, c));
  }
  return p;
}

std::vector<Part> tableAt(double x, double y, double sx, double sy, double h, Rgb c) {
  return {solid({x - sx / 2, y - sy / 2, h - 0.05}, {x + sx / 2, y + sy / 2, h}, c),
          solid({x - 0.15, y - 0.15, 0.0}, {x + 0.15, y + 0.15, h - 0.05}, shade(c, 0.7))};
}

std::vector<Part> personAt(double x, double y, Rng& rng) {
  const Rgb clothes = randomColor(rng, 40, 220);
  return {solid({x - 0.2, y - 0.15, 0.0}, {x + 0.2, y + 0.15, 1.45}, clothes),
          solid({x - 0.1, y - 0.1, 1.45}, {x + 0.1, y + 0.1, 1.72}, Rgb{210, 170, 140})};
}

std::vector<Part> robotAt(double x, double y) {
  return {solid({x - 0.3, y - 0.3, 0.0}, {x + 0.3, y + 0.3, 1.1}, Rgb{70, 72, 80}),
          solid({x - 0.12, y - 0.12, 1.1}, {x + 0.12, y + 0.12, 1.4}, Rgb{90, 90, 100})};
}

bool clearOf(const Room& room, double x, double y, double radius) {
  return (Eigen::Vector2d(x, y) - room.inside_m).norm() > kClearRadius + radius &&
         (Eigen::Vector2d(x, y) - room.door_m).norm() > kClearRadius + radius;
}

// A random free-standing spot in a room, away from where the robot stands.
Eigen::Vector2d spotIn(const Room& room, Rng& rng, double margin) {
  for (int attempt = 0; attempt < 50; ++attempt) {
    const double x = rng.uniform(room.area.min().x() + margin, room.area.max().x() - margin);
    const double y = rng.uniform(room.area.min().y() + margin, room.area.max().y() - margin);
    if (clearOf(room, x, y, margin)) return {x, y};
  }
  return room.area.max() - Eigen::Vector2d(margin, margin);
}

void addWallX(Builder& b, double x0, double x1, double y0, const std::vector<double>& doors, Rgb c) {
  // A wall along x from x0 to x1 at y0..y0+thickness with door openings centred at `doors`.
  std::vector<Part> parts;
  double x = x0;
  std::vector<double> sorted = doors;
  std::sort(sorted.begin(), sorted.end());
  for (double d : sorted) {
    parts.push_back(solid({x, y0, 0.0}, {d - kDoorWidth / 2, y0 + kWallThickness, kWallHeight}, c));
    parts.push_back(solid({d - kDoorWidth / 2, y0, kDoorHeight}, {d + kDoorWidth / 2, y0 + kWallThickness, kWallHeight}, c));
    x = d + kDoorWidth / 2;
  }
  parts.push_back(solid({x, y0, 0.0}, {x1, y0 + kWallThickness, kWallHeight}, c));
  b.add(ObjectKind::Wall, -1, std::move(parts));
}

void addWallY(Builder& b, double x0, double y0, double y1, Rgb c) {
  b.add(ObjectKind::Wall, -1, {solid({x0, y0, 0.0}, {x0 + kWallThickness, y1, kWallHeight}, c)});
}

void furnish(Builder& b, int room_index, Rng& rng) {
  const Room room = b.s.rooms[static_cast<size_t>(room_index)];
  const auto& a = room.area;
  const bool north = room.door_m.y() < a.center().y();  // door on the south side
  const double back_y = north ? a.max().y() : a.min().y();
  const double dir = north ? -1.0 : 1.0;  // from the back wall into the room
  const Rgb chair_color = rng.chance(0.5) ? Rgb{30, 30, 34} : randomColor(rng, 60, 200);
  if (room.name == "meeting room") {
    const Eigen::Vector2d c = a.center() + Eigen::Vector2d(0.0, north ? 0.6 : -0.6);  // off the robot's stand
    b.add(ObjectKind::Table, room_index, tableAt(c.x(), c.y(), 2.4, 1.0, 0.74, Rgb{150, 110, 70}));
    for (int i = 0; i < 6; ++i) {
      const double x = c.x() - 0.8 + 0.8 * (i % 3);
      const double y = c.y() + (i < 3 ? -0.8 : 0.8);
      b.add(ObjectKind::Chair, room_index, chairAt(x, y, i >= 3, chair_color));
    }
  } else if (room.name == "kitchen") {
    b.add(ObjectKind::Shelf, room_index,
          {solid({a.min().x() + 0.2, std::min(back_y, back_y + dir * 0.6), 0.0},
                 {a.max().x() - 0.2, std::max(back_y, back_y + dir * 0.6), 0.9}, Rgb{235, 235, 230})});
    const Eigen::Vector2d t = spotIn(room, rng, 0.7);
    b.add(ObjectKind::Table, room_index, tableAt(t.x(), t.y(), 1.2, 0.8, 0.75, Rgb{200, 190, 170}));
    for (int i = 0; i < 2; ++i) {
      b.add(ObjectKind::Chair, room_index, chairAt(t.x() - 0.3 + 0.6 * i, t.y() - 0.6, false, chair_color));
    }
  } else {
    const int desks = a.sizes().x() > 4.5 ? 2 : 1;
    for (int i = 0; i < desks; ++i) {
      const double x = a.min().x() + (i + 0.5) * a.sizes().x() / desks;
      const double y = back_y + dir * 0.4;
      const Rgb desk = randomColor(rng, 120, 230);
      b.add(ObjectKind::Desk, room_index,
            {solid({x - 0.7, y - 0.35, 0.0}, {x + 0.7, y + 0.35, 0.74}, desk)});
      b.add(ObjectKind::Chair, room_index, chairAt(x, y + dir * 0.75, north, chair_color));
    }
    const double sx = rng.chance(0.5) ? a.min().x() + 0.2 : a.max().x() - 0.6;
    b.add(ObjectKind::Shelf, room_index,
          {solid({sx, a.center().y() - 0.5, 0.0}, {sx + 0.4, a.center().y() + 0.5, 1.8}, randomColor(rng, 80, 200))});
  }
  const int boxes = 1 + rng.below(2);
  for (int i = 0; i < boxes; ++i) {
    const double s = rng.uniform(0.3, 0.6);
    const Eigen::Vector2d p = spotIn(room, rng, s);
    b.add(ObjectKind::Box, room_index,
          {solid({p.x() - s / 2, p.y() - s / 2, 0.0}, {p.x() + s / 2, p.y() + s / 2, s}, randomColor(rng, 90, 230))});
  }
}

void translate(Object& o, const Eigen::Vector3d& d) {
  for (Part& p : o.parts) p.box.translate(d);
}

Eigen::Vector2d centerOf(const Object& o) {
  Eigen::AlignedBox3d all;
  for (const Part& p : o.parts) all.extend(p.box);
  return all.center().head<2>();
}

}  // namespace

const char* toString(ObjectKind kind) {
  switch (kind) {
    case ObjectKind::Floor: return "floor";
    case ObjectKind::Wall: return "wall";
    case ObjectKind::Door: return "door";
    case ObjectKind::Desk: return "desk";
    case ObjectKind::Chair: return "chair";
    case ObjectKind::Shelf: return "shelf";
    case ObjectKind::Table: return "table";
    case ObjectKind::Box: return "box";
    case ObjectKind::Person: return "person";
    case ObjectKind::Robot: return "robot";
  }
  return "unknown";
}

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

SceneState makeScene(const std::string& preset, uint64_t seed) {
  Rng rng(mix(seed, 0x5ce4e));
  Builder b;
  const Rgb wall_color = randomColor(rng, 190, 235);
  if (preset == "tiny") {
    const Eigen::AlignedBox2d area(Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(4.0, 3.5));
    b.add(ObjectKind::Floor, -1, {solid({-0.2, -0.2, -0.1}, {4.2, 3.7, 0.0}, Rgb{140, 125, 110})});
    addWallX(b, -0.1, 4.1, -0.1, {2.0}, wall_color);
    addWallX(b, -0.1, 4.1, 3.5, {}, wall_color);
    addWallY(b, -0.1, 0.0, 3.5, wall_color);
    addWallY(b, 4.0, 0.0, 3.5, wall_color);
    b.s.rooms.push_back(Room{"office", area, {2.0, -0.05}, {2.0, 1.6}, 0});
    Object& door = b.add(ObjectKind::Door, 0, {solid({1.5, -0.08, 0.0}, {2.5, -0.02, kDoorHeight}, Rgb{120, 80, 50})});
    b.s.rooms[0].door_object = door.id;
    furnish(b, 0, rng);
  } else if (preset == "office" || preset == "floor66") {
    const bool big = preset == "floor66";
    const double length = big ? 40.0 : 12.0, depth = big ? 8.9 : 5.0, width = big ? 5.0 : 4.0;
    const int per_side = static_cast<int>(length / width);
    const double corridor = 2.0;
    b.add(ObjectKind::Floor, -1,
          {solid({-0.2, big ? -depth - 0.3 : -0.3, -0.1}, {length + 0.2, corridor + depth + 0.3, 0.0},
                 Rgb{140, 125, 110})});
    std::vector<double> north_doors, south_doors;
    for (int i = 0; i < per_side; ++i) north_doors.push_back((i + 0.5) * width);
    if (big) south_doors = north_doors;
    addWallX(b, -0.1, length + 0.1, corridor, north_doors, wall_color);          // corridor, north side
    addWallX(b, -0.1, length + 0.1, corridor + depth + kWallThickness, {}, wall_color);
    addWallX(b, -0.1, length + 0.1, -kWallThickness, south_doors, wall_color);  // corridor, south side
    if (big) addWallX(b, -0.1, length + 0.1, -depth - 2 * kWallThickness, {}, wall_color);
    addWallY(b, -0.1, big ? -depth - kWallThickness : 0.0, corridor + depth + kWallThickness, wall_color);
    addWallY(b, length, big ? -depth - kWallThickness : 0.0, corridor + depth + kWallThickness, wall_color);
    for (int i = 1; i < per_side; ++i) {
      addWallY(b, i * width - kWallThickness / 2, corridor + kWallThickness, corridor + depth + kWallThickness, wall_color);
      if (big) addWallY(b, i * width - kWallThickness / 2, -depth - kWallThickness, -kWallThickness, wall_color);
    }
    b.s.rooms.push_back(Room{"corridor", Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(length, corridor)),
                             {0, 0}, {0, 1.0}, 0});
    const std::vector<std::string> names_small = {"office", "kitchen", "meeting room"};
    for (int side = 0; side < (big ? 2 : 1); ++side) {
      for (int i = 0; i < per_side; ++i) {
        const double x0 = i * width + (i > 0 ? kWallThickness / 2 : 0.0);
        const double x1 = (i + 1) * width - (i + 1 < per_side ? kWallThickness / 2 : 0.0);
        Room r;
        if (big) {
          const int k = side * per_side + i;
          r.name = k == 2 ? "kitchen" : (k == 5 || k == 12) ? "meeting room" : "office " + std::to_string(k + 1);
        } else {
          r.name = names_small[static_cast<size_t>(i)];
        }
        const double cx = (i + 0.5) * width;
        if (side == 0) {
          r.area = Eigen::AlignedBox2d(Eigen::Vector2d(x0, corridor + kWallThickness),
                                       Eigen::Vector2d(x1, corridor + kWallThickness + depth));
          r.door_m = {cx, corridor + kWallThickness / 2};
          r.inside_m = {cx, corridor + kWallThickness + 1.2};
        } else {
          r.area = Eigen::AlignedBox2d(Eigen::Vector2d(x0, -kWallThickness - depth), Eigen::Vector2d(x1, -kWallThickness));
          r.door_m = {cx, -kWallThickness / 2};
          r.inside_m = {cx, -kWallThickness - 1.2};
        }
        b.s.rooms.push_back(r);
        const int index = static_cast<int>(b.s.rooms.size() - 1);
        const double dy = side == 0 ? corridor + 0.02 : -kWallThickness + 0.02;
        Object& door = b.add(ObjectKind::Door, index,
                             {solid({cx - kDoorWidth / 2, dy, 0.0}, {cx + kDoorWidth / 2, dy + 0.06, kDoorHeight},
                                    Rgb{120, 80, 50})});
        b.s.rooms.back().door_object = door.id;
        furnish(b, index, rng);
      }
    }
  } else {
    throw UsageError("unknown simulator preset '" + preset + "' (use tiny, office or floor66)");
  }
  // Most doors stand open at first.
  for (Object& o : b.s.objects) {
    if (o.kind == ObjectKind::Door) o.present = rng.chance(0.3);
  }
  // A person and a robot that visit in some sessions; absent at first.
  Object& person = b.add(ObjectKind::Person, -1, personAt(0, 0, rng));
  person.present = false;
  Object& other_robot = b.add(ObjectKind::Robot, -1, robotAt(0, 0));
  other_robot.present = false;

  for (Object& o : b.s.objects) translate(o, kOffset);
  for (Room& r : b.s.rooms) {
    r.area.translate(kOffset.head<2>());
    r.door_m += kOffset.head<2>();
    r.inside_m += kOffset.head<2>();
  }
  for (const Object& o : b.s.objects) {
    for (const Part& p : o.parts) b.s.bounds.extend(p.box);
  }
  return b.s;
}

std::vector<std::pair<uint32_t, std::string>> applyChanges(SceneState& state, uint64_t seed, int session) {
  Rng rng(mix(seed, 1000 + static_cast<uint64_t>(session)));
  std::vector<std::pair<uint32_t, std::string>> events;
  if (rng.chance(0.15)) return events;  // a session in which nothing changed
  auto roomOf = [&](const Object& o) -> const Room* {
    return o.room >= 0 ? &state.rooms[static_cast<size_t>(o.room)] : nullptr;
  };
  auto moveTo = [&](Object& o, const Eigen::Vector2d& target) {
    const Eigen::Vector2d d = target - centerOf(o);
    translate(o, Eigen::Vector3d(d.x(), d.y(), 0.0));
  };
  const size_t n = state.objects.size();
  for (size_t i = 0; i < n; ++i) {
    Object& o = state.objects[i];
    const Room* room = roomOf(o);
    switch (o.kind) {
      case ObjectKind::Door:
        if (rng.chance(0.25)) {
          o.present = !o.present;
          events.emplace_back(o.id, o.present ? "door_closed" : "door_opened");
        }
        break;
      case ObjectKind::Chair: {
        if (!room) break;
        const bool meeting = room->name == "meeting room";
        if (rng.chance(meeting ? 0.5 : 0.3)) {
          const Eigen::Vector2d c = centerOf(o);
          const double reach = meeting ? 0.6 : 0.25;
          Eigen::Vector2d t(c.x() + rng.uniform(-reach, reach), c.y() + rng.uniform(-reach, reach));
          const Eigen::AlignedBox2d inner(room->area.min() + Eigen::Vector2d(0.3, 0.3),
                                          room->area.max() - Eigen::Vector2d(0.3, 0.3));
          t = t.cwiseMax(inner.min()).cwiseMin(inner.max());
          if (clearOf(*room, t.x(), t.y(), 0.3)) {
            moveTo(o, t);
            events.emplace_back(o.id, "moved");
          }
        }
        break;
      }
      case ObjectKind::Box:
        if (!room) break;
        if (o.present && rng.chance(0.08)) {
          o.present = false;
          events.emplace_back(o.id, "removed");
        } else if (o.present && rng.chance(0.08)) {
          moveTo(o, spotIn(*room, rng, 0.4));
          events.emplace_back(o.id, "moved");
        }
        break;
      case ObjectKind::Person:
      case ObjectKind::Robot: {
        const bool person = o.kind == ObjectKind::Person;
        const bool now = rng.chance(person ? 0.3 : 0.15);
        if (!now && !o.present) break;
        if (!now) {
          o.present = false;
          events.emplace_back(o.id, "left");
          break;
        }
        // Somewhere in the corridor off its centre line, or (a person) in a room.
        Eigen::Vector2d target;
        int room_index = 0;
        if (person && state.rooms.size() > 1 && rng.chance(0.5)) {
          room_index = 1 + rng.below(static_cast<int>(state.rooms.size()) - 1);
          target = spotIn(state.rooms[static_cast<size_t>(room_index)], rng, 0.3);
        } else {
          const Room& corridor = state.rooms[0];
          const double side = rng.chance(0.5) ? 0.35 : corridor.area.sizes().y() - 0.35;
          target = {rng.uniform(corridor.area.min().x() + 1.5, corridor.area.max().x() - 1.5),
                    corridor.area.min().y() + side};
          room_index = state.rooms.size() > 1 ? 0 : -1;
        }
        if (state.rooms.size() == 1) {  // tiny: one room only
          room_index = 0;
          target = spotIn(state.rooms[0], rng, 0.3);
        }
        const bool was = o.present;
        moveTo(o, target);
        o.room = room_index;
        o.present = true;
        events.emplace_back(o.id, was ? "moved" : "appeared");
        break;
      }
      default:
        break;
    }
  }
  // New boxes now and then.
  if (rng.chance(0.3) && !state.rooms.empty()) {
    const int room_index = state.rooms.size() > 1 ? 1 + rng.below(static_cast<int>(state.rooms.size()) - 1) : 0;
    const Room& room = state.rooms[static_cast<size_t>(room_index)];
    const double s = rng.uniform(0.3, 0.6);
    const Eigen::Vector2d p = spotIn(room, rng, s);
    Object o;
    o.id = 0;
    for (const Object& other : state.objects) o.id = std::max(o.id, other.id + 1);
    o.kind = ObjectKind::Box;
    o.room = room_index;
    o.parts = {solid({p.x() - s / 2, p.y() - s / 2, kOffset.z()}, {p.x() + s / 2, p.y() + s / 2, kOffset.z() + s},
                     randomColor(rng, 90, 230))};
    events.emplace_back(o.id, "added");
    state.objects.push_back(std::move(o));
  }
  return events;
}

// ---------------------------------------------------------------------------------------------
// Ground truth

std::vector<VoxelKey> objectVoxels(const Object& object, const KeyGrid& grid) {
  std::vector<VoxelKey> keys;
  if (!object.present) return keys;
  const double res = grid.resolution_m();
  auto index = [&](double v) { return static_cast<int64_t>(std::floor(v / res)) + kKeyOrigin; };
  // Last voxel index touched by [lo, hi): a face that ends on a voxel face does not enter it.
  auto lastIndex = [&](double hi) { return static_cast<int64_t>(std::ceil(hi / res)) - 1 + kKeyOrigin; };
  // Parts are solid: every voxel that overlaps one holds geometry (a wall's or a box's inside
  // is occupied space, even though no sensor sees it).
  for (const Part& p : object.parts) {
    const Eigen::Vector3d lo = p.box.min(), hi = p.box.max();
    int64_t first[3], last[3];
    for (int a = 0; a < 3; ++a) {
      first[a] = std::max<int64_t>(0, index(lo[a]));
      last[a] = std::min<int64_t>(kKeysPerAxis - 1, lastIndex(hi[a]));
    }
    for (int64_t z = first[2]; z <= last[2]; ++z) {
      for (int64_t y = first[1]; y <= last[1]; ++y) {
        for (int64_t x = first[0]; x <= last[0]; ++x) {
          keys.push_back(VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)});
        }
      }
    }
  }
  std::sort(keys.begin(), keys.end(), [](const VoxelKey& a, const VoxelKey& b) { return mortonEncode(a) < mortonEncode(b); });
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

std::vector<VoxelKey> truthOccupancy(const SceneState& state, const KeyGrid& grid) {
  std::vector<VoxelKey> all;
  for (const Object& o : state.objects) {
    const auto k = objectVoxels(o, grid);
    all.insert(all.end(), k.begin(), k.end());
  }
  std::sort(all.begin(), all.end(), [](const VoxelKey& a, const VoxelKey& b) { return mortonEncode(a) < mortonEncode(b); });
  all.erase(std::unique(all.begin(), all.end()), all.end());
  return all;
}

OccupancyScore scoreOccupancy(const SessionMap& map, const std::vector<VoxelKey>& truth) {
  OccupancyScore s;
  map.forEachLeaf([&](const LeafView& leaf) {
    if (leaf.level == 0 && leaf.counters.state() == VoxelState::Occupied) {
      ++s.predicted;
      if (std::binary_search(truth.begin(), truth.end(), leaf.key, [](const VoxelKey& a, const VoxelKey& b) {
            return mortonEncode(a) < mortonEncode(b);
          })) {
        ++s.true_positive;
      }
    }
  });
  for (const VoxelKey& k : truth) {
    if (map.stateOf(k) != VoxelState::Unknown) ++s.truth_known;
  }
  s.precision = s.predicted ? static_cast<double>(s.true_positive) / static_cast<double>(s.predicted) : 0.0;
  s.recall = s.truth_known ? static_cast<double>(s.true_positive) / static_cast<double>(s.truth_known) : 0.0;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Rendering

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

// ---------------------------------------------------------------------------------------------
// Sessions, patrols and output

namespace {

struct PresetPlan {
  int sessions;
  double days;
};

PresetPlan presetPlan(const std::string& preset) {
  if (preset == "tiny") return {3, 2};
  if (preset == "office") return {6, 4};
  return {66, 45};
}

struct Shot {
  Eigen::Vector2d position;
  double yaw;
};

// Stops and pan angles of one patrol through the rooms whose doors are open (each visited
// with probability 0.85, all of them in the first session).
std::vector<Shot> patrol(const SceneState& state, Rng& rng, bool first_session) {
  std::vector<Shot> shots;
  const double deg = std::numbers::pi / 180.0;
  auto pan = [&](const Eigen::Vector2d& p, int steps, double start) {
    for (int k = 0; k < steps; ++k) shots.push_back({p, start + 2.0 * std::numbers::pi * k / steps});
  };
  if (state.rooms.size() == 1) {  // tiny: four stops inside the room
    const auto& a = state.rooms[0].area;
    for (const Eigen::Vector2d& f : {Eigen::Vector2d(0.3, 0.35), Eigen::Vector2d(0.7, 0.35), Eigen::Vector2d(0.7, 0.65),
                                     Eigen::Vector2d(0.3, 0.65)}) {
      pan(a.min() + f.cwiseProduct(a.sizes()), 8, rng.uniform(0, 45 * deg));
    }
    return shots;
  }
  const Room& corridor = state.rooms[0];
  const double y = corridor.area.center().y();
  std::vector<const Room*> rooms;
  for (size_t r = 1; r < state.rooms.size(); ++r) rooms.push_back(&state.rooms[r]);
  std::sort(rooms.begin(), rooms.end(), [](const Room* a, const Room* b) { return a->door_m.x() < b->door_m.x(); });
  size_t next_room = 0;
  // The stops as they have always been computed: an integer counter would move them by rounding
  // and change every simulated dataset.
  // NOLINTNEXTLINE(clang-analyzer-security.FloatLoopCounter)
  for (double x = corridor.area.min().x() + 0.6; x < corridor.area.max().x() - 0.4; x += 1.0) {
    for (double a : {-60.0, 0.0, 60.0}) shots.push_back({{x, y}, a * deg});
    // Rooms whose door lies before the next stop: visit when the door is open and the patrol
    // includes it this time.
    while (next_room < rooms.size() && rooms[next_room]->door_m.x() < x + 1.0) {
      const Room& r = *rooms[next_room++];
      bool open = true;
      for (const Object& o : state.objects) {
        if (o.id == r.door_object) open = !o.present;
      }
      if (!open || (!first_session && !rng.chance(0.85))) continue;
      shots.push_back({{r.door_m.x(), y}, std::atan2(r.inside_m.y() - y, 0.0)});
      pan(r.inside_m, 8, rng.uniform(0, 45 * deg));
    }
  }
  return shots;
}

Eigen::Isometry3d cameraPose(const Eigen::Vector2d& p, double yaw) {
  const double pitch = kCameraPitchDeg * std::numbers::pi / 180.0;
  const Eigen::Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
  const Eigen::Vector3d right(std::sin(yaw), -std::cos(yaw), 0.0);
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = down;
  T.linear().col(2) = forward;
  T.translation() = Eigen::Vector3d(p.x(), p.y(), kOffset.z() + kCameraHeight);
  return T;
}

std::string poseLine(double stamp, const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  char buf[256];
  std::snprintf(buf, sizeof buf, "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", stamp, T.translation().x(),
                T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

void writeText(const fs::path& path, const std::string& text) {
  io::writeFileAtomic(path, std::vector<uint8_t>(text.begin(), text.end()));
}

nlohmann::json objectsJson(const SceneState& state) {
  nlohmann::json objects = nlohmann::json::array();
  for (const Object& o : state.objects) {
    if (!o.present) continue;
    nlohmann::json parts = nlohmann::json::array();
    for (const Part& p : o.parts) {
      parts.push_back({{"min", {p.box.min().x(), p.box.min().y(), p.box.min().z()}},
                       {"max", {p.box.max().x(), p.box.max().y(), p.box.max().z()}},
                       {"color", {p.face_colors[5].r, p.face_colors[5].g, p.face_colors[5].b}}});
    }
    const Eigen::Vector2d c = centerOf(o);
    objects.push_back({{"id", o.id},
                       {"kind", toString(o.kind)},
                       {"room", o.room >= 0 ? state.rooms[static_cast<size_t>(o.room)].name : ""},
                       {"position", {c.x(), c.y()}},
                       {"parts", parts}});
  }
  return objects;
}

bool containsKey(const std::vector<VoxelKey>& sorted, const VoxelKey& k) {
  return std::binary_search(sorted.begin(), sorted.end(), k,
                            [](const VoxelKey& a, const VoxelKey& b) { return mortonEncode(a) < mortonEncode(b); });
}

}  // namespace

SimulationSummary simulate(const SimulationSettings& settings, const fs::path& out,
                           const SimulationProgress& progress) {
  const auto started = std::chrono::steady_clock::now();
  const PresetPlan plan = presetPlan(settings.preset);
  SceneState state = makeScene(settings.preset, settings.seed);  // validates the preset
  const int sessions = settings.sessions > 0 ? settings.sessions : plan.sessions;
  if (settings.sessions < 0 || sessions > 1000) throw UsageError("--sessions must lie between 1 and 1000");
  if (!(settings.resolution_scale >= 0.1 && settings.resolution_scale <= 1.0)) {
    throw UsageError("--resolution-scale must lie between 0.1 and 1");
  }
  if (!(settings.noise_per_m2 >= 0.0) || !(settings.localisation_offset_m >= 0.0) ||
      !(settings.localisation_yaw_deg >= 0.0) || !(settings.drift_per_frame_m >= 0.0)) {
    throw UsageError("noise and localisation errors must be non-negative");
  }
  const KeyGrid grid(settings.voxel_resolution_m);
  const Camera camera = kinectCamera(settings.resolution_scale);
  SensorModel sensor;
  sensor.noise_per_m2 = settings.noise_per_m2;
  std::error_code ec;
  fs::create_directories(out / "truth", ec);
  if (ec) throw IoError(out.string() + ": cannot create folder (" + ec.message() + ")");
  std::unique_ptr<tbb::global_control> limit;
  if (settings.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<size_t>(settings.threads));
  }

  // Session times: 2 or 3 sessions on a recording day, at different hours, a day or two apart.
  Rng time_rng(mix(settings.seed, 77));
  std::vector<double> times, hours;
  const double start = 1330560000.0;  // 2012-03-01T00:00:00Z
  double day = 0.0;
  while (static_cast<int>(times.size()) < sessions) {
    static constexpr double kHours[] = {9.0, 11.5, 14.0, 16.5, 19.0};
    const int today = settings.preset == "tiny" ? 1 : 2 + (time_rng.chance(0.5) ? 1 : 0);
    int first = time_rng.below(5 - today + 1);
    for (int k = 0; k < today && static_cast<int>(times.size()) < sessions; ++k) {
      const double h = kHours[first + k] + time_rng.uniform(0.0, 1.0);
      hours.push_back(h);
      times.push_back(start + 86400.0 * day + 3600.0 * h);
    }
    day += plan.days * 2.5 / plan.sessions >= 1.0 ? 1.0 + time_rng.below(2) : 1.0;
  }

  SimulationSummary summary;
  nlohmann::json sessions_json = nlohmann::json::array(), events_json = nlohmann::json::array();
  std::vector<VoxelKey> previous_truth;
  SceneState previous_state;
  for (int s = 0; s < sessions; ++s) {
    std::vector<std::pair<uint32_t, std::string>> changes;
    if (s > 0) changes = applyChanges(state, settings.seed, s);
    const std::vector<VoxelKey> truth = truthOccupancy(state, grid);
    // Change events with the truth voxels each one changes.
    for (const auto& [id, kind] : changes) {
      const Object* before = nullptr;
      const Object* after = nullptr;
      for (const Object& o : previous_state.objects) {
        if (o.id == id) before = &o;
      }
      for (const Object& o : state.objects) {
        if (o.id == id) after = &o;
      }
      std::vector<VoxelKey> candidates;
      if (before) candidates = objectVoxels(*before, grid);
      if (after) {
        const auto v = objectVoxels(*after, grid);
        candidates.insert(candidates.end(), v.begin(), v.end());
      }
      ChangeEvent e;
      e.object = id;
      e.object_kind = after ? after->kind : before->kind;
      e.kind = kind;
      for (const VoxelKey& k : candidates) {
        if (containsKey(previous_truth, k) != containsKey(truth, k)) e.voxels.push_back(k);
      }
      std::sort(e.voxels.begin(), e.voxels.end());
      e.voxels.erase(std::unique(e.voxels.begin(), e.voxels.end()), e.voxels.end());
      if (e.voxels.empty()) continue;  // hidden by other objects: nothing a map could see
      nlohmann::json voxels = nlohmann::json::array();
      for (const VoxelKey& k : e.voxels) voxels.push_back({k.x, k.y, k.z});
      events_json.push_back({{"from_session", s - 1},
                             {"to_session", s},
                             {"object", e.object},
                             {"object_kind", toString(e.object_kind)},
                             {"kind", e.kind},
                             {"voxel_count", e.voxels.size()},
                             {"voxels", voxels}});
      ++summary.events;
    }

    // The patrol, true and estimated poses.
    Rng path_rng(mix(settings.seed, 5000 + static_cast<uint64_t>(s)));
    const std::vector<Shot> shots = patrol(state, path_rng, s == 0);
    const double off_x = settings.localisation_offset_m * path_rng.normal();
    const double off_y = settings.localisation_offset_m * path_rng.normal();
    const double off_yaw = settings.localisation_yaw_deg * std::numbers::pi / 180.0 * path_rng.normal();
    std::vector<Eigen::Isometry3d> true_poses, estimated;
    double dx = off_x, dy = off_y, dyaw = off_yaw;
    for (const Shot& shot : shots) {
      const Eigen::Isometry3d T = cameraPose(shot.position, shot.yaw);
      dx += settings.drift_per_frame_m * path_rng.normal();
      dy += settings.drift_per_frame_m * path_rng.normal();
      dyaw += 0.01 * std::numbers::pi / 180.0 * path_rng.normal();
      Eigen::Isometry3d E = T;
      E.linear() = Eigen::AngleAxisd(dyaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * T.linear();
      E.translation() += Eigen::Vector3d(dx, dy, 0.0);
      true_poses.push_back(T);
      estimated.push_back(E);
    }

    char name[32];
    std::snprintf(name, sizeof name, "session_%02d", s);
    const fs::path dir = out / name;
    fs::create_directories(dir / "rgb", ec);
    fs::create_directories(dir / "depth", ec);
    if (ec) throw IoError(dir.string() + ": cannot create folder (" + ec.message() + ")");
    const Renderer renderer(state);
    std::vector<std::string> stamps(shots.size());
    for (size_t i = 0; i < shots.size(); ++i) {
      char st[32];
      std::snprintf(st, sizeof st, "%.6f", times[static_cast<size_t>(s)] + 0.5 * static_cast<double>(i));
      stamps[i] = st;
    }
    parallelFor(shots.size(), settings.threads, [&](size_t i) {
      const RenderedFrame f = renderer.render(camera, true_poses[i], sensor, hours[static_cast<size_t>(s)],
                                              mix(settings.seed, (static_cast<uint64_t>(s) << 20) + i));
      io::writePng(dir / "rgb" / (stamps[i] + ".png"), f.rgb);
      io::writePng(dir / "depth" / (stamps[i] + ".png"), f.depth);
    });
    std::string rgb_txt = "# color images\n# timestamp filename\n", depth_txt = "# depth maps\n# timestamp filename\n";
    std::string gt = "# true camera poses\n# timestamp tx ty tz qx qy qz qw\n";
    std::string traj = "# estimated camera poses (localisation with offset and drift)\n# timestamp tx ty tz qx qy qz qw\n";
    for (size_t i = 0; i < shots.size(); ++i) {
      const double stamp = times[static_cast<size_t>(s)] + 0.5 * static_cast<double>(i);
      rgb_txt += stamps[i] + " rgb/" + stamps[i] + ".png\n";
      depth_txt += stamps[i] + " depth/" + stamps[i] + ".png\n";
      gt += poseLine(stamp, true_poses[i]);
      traj += poseLine(stamp, estimated[i]);
    }
    writeText(dir / "rgb.txt", rgb_txt);
    writeText(dir / "depth.txt", depth_txt);
    writeText(dir / "groundtruth.txt", gt);
    writeText(dir / "trajectory.txt", traj);
    char k[128];
    std::snprintf(k, sizeof k, "%.6f %.6f %.6f %.6f\n", camera.fx, camera.fy, camera.cx, camera.cy);
    writeText(dir / "camera-intrinsics.txt", k);

    // Ground truth of this session.
    SessionMap occupancy(grid.resolution_m());
    VoxelCounters occupied;
    occupied.hits = 1;
    std::vector<VoxelCounters> values(truth.size(), occupied);
    occupancy.addMany(truth, values);
    char truth_name[64];
    std::snprintf(truth_name, sizeof truth_name, "occupancy_%02d.cmap", s);
    io::writeSessionMap(out / "truth" / truth_name,
                        occupancy, {{"created_by", "chronomap simulate"}, {"truth", true}, {"session", s}});
    std::snprintf(truth_name, sizeof truth_name, "objects_%02d.json", s);
    writeText(out / "truth" / truth_name, objectsJson(state).dump(1) + "\n");

    sessions_json.push_back({{"index", s},
                             {"dir", name},
                             {"time_s", times[static_cast<size_t>(s)]},
                             {"time", formatTime(times[static_cast<size_t>(s)])},
                             {"hour", hours[static_cast<size_t>(s)]},
                             {"frames", shots.size()},
                             {"changes", changes.size()},
                             {"localisation_offset", {off_x, off_y, off_yaw * 180.0 / std::numbers::pi}}});
    summary.session_dirs.push_back(dir);
    summary.times_s.push_back(times[static_cast<size_t>(s)]);
    summary.hours.push_back(hours[static_cast<size_t>(s)]);
    summary.frames += shots.size();
    previous_truth = truth;
    previous_state = state;
    if (progress) progress(static_cast<size_t>(s) + 1, static_cast<size_t>(sessions));
  }
  nlohmann::json scene = {{"created_by", "chronomap simulate"},
                          {"preset", settings.preset},
                          {"seed", settings.seed},
                          {"voxel_resolution_m", settings.voxel_resolution_m},
                          {"camera",
                           {{"width", camera.width},
                            {"height", camera.height},
                            {"fx", camera.fx},
                            {"fy", camera.fy},
                            {"cx", camera.cx},
                            {"cy", camera.cy},
                            {"height_m", kCameraHeight},
                            {"pitch_deg", kCameraPitchDeg}}},
                          {"sensor",
                           {{"noise_per_m2", sensor.noise_per_m2},
                            {"depth_scale", sensor.depth_scale},
                            {"min_range_m", sensor.min_range_m},
                            {"max_range_m", sensor.max_range_m}}},
                          {"rooms", nlohmann::json::array()},
                          {"sessions", sessions_json},
                          {"events", events_json}};
  for (const Room& r : state.rooms) {
    scene["rooms"].push_back({{"name", r.name},
                              {"min", {r.area.min().x(), r.area.min().y()}},
                              {"max", {r.area.max().x(), r.area.max().y()}}});
  }
  writeText(out / "scene.json", scene.dump(1) + "\n");
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return summary;
}

}  // namespace chronomap::sim
