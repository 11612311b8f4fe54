// Scene generation: the building of a preset from a seed, and the change processes between
// sessions.
#include "chronomap/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "chronomap/core/error.h"
#include "internal.h"

namespace chronomap {

namespace {

using sim_detail::kOffset;
using sim_detail::mix;
using sim_detail::Rng;
using sim_detail::translate;

constexpr double kWallHeight = 2.5;
constexpr double kWallThickness = 0.1;
constexpr double kDoorWidth = 1.0;
constexpr double kDoorHeight = 2.1;
constexpr double kClearRadius = 0.8;  // around the places the robot stands

Rgb shade(Rgb c, double f) {
  auto s = [f](uint8_t v) { return static_cast<uint8_t>(std::clamp(std::lround(v * f), 0L, 255L)); };
  return {s(c.r), s(c.g), s(c.b)};
}

Part solid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Rgb c) {
  Part p;
  p.box = Eigen::AlignedBox3d(lo, hi);
  // Sides slightly darker than the top, as under ceiling light.
  p.face_colours = {shade(c, 0.85), shade(c, 0.9), shade(c, 0.8), shade(c, 0.95), shade(c, 0.6), c};
  return p;
}

Rgb randomColour(Rng& rng, int lo, int hi) {
  return {static_cast<uint8_t>(lo + rng.below(hi - lo)), static_cast<uint8_t>(lo + rng.below(hi - lo)),
          static_cast<uint8_t>(lo + rng.below(hi - lo))};
}

// The shiny faces of a new object's parts, by kind (no randomness, so that the scene, its truth
// and every ideal frame stay as they were): the top of a desk or table (varnish), a robot all
// over and the cleaning cart's handle (metal).
void markShinyFaces(ObjectKind kind, std::vector<Part>& parts) {
  constexpr uint8_t kTop = 1u << 5, kAll = 0x3f;
  if (parts.empty()) return;
  const auto highest = std::max_element(parts.begin(), parts.end(), [](const Part& a, const Part& b) {
    return a.box.max().z() < b.box.max().z();
  });
  switch (kind) {
    case ObjectKind::Desk:
    case ObjectKind::Table: highest->shiny_faces = kTop; break;
    case ObjectKind::Robot:
      for (Part& p : parts) p.shiny_faces = kAll;
      break;
    case ObjectKind::Cart: highest->shiny_faces = kAll; break;
    default: break;
  }
}

struct Builder {
  SceneState s;
  uint32_t next_id = 0;
  Object& add(ObjectKind kind, int room, std::vector<Part> parts) {
    Object o;
    o.id = next_id++;
    o.kind = kind;
    o.room = room;
    markShinyFaces(kind, parts);
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
  const Rgb clothes = randomColour(rng, 40, 220);
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
  const Rgb chair_colour = rng.chance(0.5) ? Rgb{30, 30, 34} : randomColour(rng, 60, 200);
  if (room.name == "meeting room") {
    const Eigen::Vector2d c = a.center() + Eigen::Vector2d(0.0, north ? 0.6 : -0.6);  // off the robot's stand
    b.add(ObjectKind::Table, room_index, tableAt(c.x(), c.y(), 2.4, 1.0, 0.74, Rgb{150, 110, 70}));
    for (int i = 0; i < 6; ++i) {
      const double x = c.x() - 0.8 + 0.8 * (i % 3);
      const double y = c.y() + (i < 3 ? -0.8 : 0.8);
      b.add(ObjectKind::Chair, room_index, chairAt(x, y, i >= 3, chair_colour));
    }
  } else if (room.name == "kitchen") {
    b.add(ObjectKind::Shelf, room_index,
          {solid({a.min().x() + 0.2, std::min(back_y, back_y + dir * 0.6), 0.0},
                 {a.max().x() - 0.2, std::max(back_y, back_y + dir * 0.6), 0.9}, Rgb{235, 235, 230})});
    const Eigen::Vector2d t = spotIn(room, rng, 0.7);
    b.add(ObjectKind::Table, room_index, tableAt(t.x(), t.y(), 1.2, 0.8, 0.75, Rgb{200, 190, 170}));
    for (int i = 0; i < 2; ++i) {
      b.add(ObjectKind::Chair, room_index, chairAt(t.x() - 0.3 + 0.6 * i, t.y() - 0.6, false, chair_colour));
    }
  } else {
    const int desks = a.sizes().x() > 4.5 ? 2 : 1;
    for (int i = 0; i < desks; ++i) {
      const double x = a.min().x() + (i + 0.5) * a.sizes().x() / desks;
      const double y = back_y + dir * 0.4;
      const Rgb desk = randomColour(rng, 120, 230);
      b.add(ObjectKind::Desk, room_index,
            {solid({x - 0.7, y - 0.35, 0.0}, {x + 0.7, y + 0.35, 0.74}, desk)});
      b.add(ObjectKind::Chair, room_index, chairAt(x, y + dir * 0.75, north, chair_colour));
    }
    const double sx = rng.chance(0.5) ? a.min().x() + 0.2 : a.max().x() - 0.6;
    b.add(ObjectKind::Shelf, room_index,
          {solid({sx, a.center().y() - 0.5, 0.0}, {sx + 0.4, a.center().y() + 0.5, 1.8}, randomColour(rng, 80, 200))});
  }
  const int boxes = 1 + rng.below(2);
  for (int i = 0; i < boxes; ++i) {
    const double s = rng.uniform(0.3, 0.6);
    const Eigen::Vector2d p = spotIn(room, rng, s);
    b.add(ObjectKind::Box, room_index,
          {solid({p.x() - s / 2, p.y() - s / 2, 0.0}, {p.x() + s / 2, p.y() + s / 2, s}, randomColour(rng, 90, 230))});
  }
}

}  // namespace

namespace sim_detail {

Eigen::Vector2d centerOf(const Object& o) {
  Eigen::AlignedBox3d all;
  for (const Part& p : o.parts) all.extend(p.box);
  return all.center().head<2>();
}

}  // namespace sim_detail

using sim_detail::centerOf;

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
    case ObjectKind::Cart: return "cart";
  }
  return "unknown";
}

ObjectKind parseObjectKind(const std::string& name) {
  for (ObjectKind k : {ObjectKind::Floor, ObjectKind::Wall, ObjectKind::Door, ObjectKind::Desk, ObjectKind::Chair,
                       ObjectKind::Shelf, ObjectKind::Table, ObjectKind::Box, ObjectKind::Person, ObjectKind::Robot,
                       ObjectKind::Cart}) {
    if (name == toString(k)) return k;
  }
  throw FormatError("unknown object kind '" + name + "'");
}

const char* toString(EventKind kind) {
  switch (kind) {
    case EventKind::DoorOpened: return "door_opened";
    case EventKind::DoorClosed: return "door_closed";
    case EventKind::Moved: return "moved";
    case EventKind::Added: return "added";
    case EventKind::Removed: return "removed";
    case EventKind::Appeared: return "appeared";
    case EventKind::Left: return "left";
  }
  return "unknown";
}

EventKind parseEventKind(const std::string& name) {
  for (EventKind k : {EventKind::DoorOpened, EventKind::DoorClosed, EventKind::Moved, EventKind::Added,
                      EventKind::Removed, EventKind::Appeared, EventKind::Left}) {
    if (name == toString(k)) return k;
  }
  throw FormatError("unknown change event kind '" + name + "'");
}

uint64_t siteFloorSeed(uint64_t seed, int floor) { return mix(seed, 0x517e0000ULL + static_cast<uint64_t>(floor)); }

SceneState siteFloor(uint64_t seed, int floor) { return makeScene("floor66", siteFloorSeed(seed, floor)); }

SceneState stackFloors(const std::vector<SceneState>& floors) {
  SceneState site;
  for (size_t f = 0; f < floors.size(); ++f) {
    const uint32_t id_offset = static_cast<uint32_t>(f) * kSiteIdStride;
    const int room_offset = static_cast<int>(site.rooms.size());
    const Eigen::Vector3d up(0.0, 0.0, static_cast<double>(f) * kSiteFloorHeight_m);
    for (const Room& r : floors[f].rooms) {
      Room room = r;
      room.name += " (floor " + std::to_string(f) + ")";
      room.door_object += id_offset;
      site.rooms.push_back(std::move(room));
    }
    for (const Object& o : floors[f].objects) {
      Object object = o;
      object.id += id_offset;
      if (object.room >= 0) object.room += room_offset;
      translate(object, up);
      site.objects.push_back(std::move(object));
    }
    if (!floors[f].bounds.isEmpty()) {
      site.bounds.extend(floors[f].bounds.min() + up);
      site.bounds.extend(floors[f].bounds.max() + up);
    }
  }
  return site;
}

SceneState makeScene(const std::string& preset, uint64_t seed) {
  if (preset == "site") {
    std::vector<SceneState> floors;
    for (int f = 0; f < kSiteFloors; ++f) floors.push_back(siteFloor(seed, f));
    return stackFloors(floors);
  }
  Rng rng(mix(seed, 0x5ce4e));
  Builder b;
  const Rgb wall_colour = randomColour(rng, 190, 235);
  if (preset == "tiny") {
    const Eigen::AlignedBox2d area(Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(4.0, 3.5));
    b.add(ObjectKind::Floor, -1, {solid({-0.2, -0.2, -0.1}, {4.2, 3.7, 0.0}, Rgb{140, 125, 110})});
    addWallX(b, -0.1, 4.1, -0.1, {2.0}, wall_colour);
    addWallX(b, -0.1, 4.1, 3.5, {}, wall_colour);
    addWallY(b, -0.1, 0.0, 3.5, wall_colour);
    addWallY(b, 4.0, 0.0, 3.5, wall_colour);
    b.s.rooms.push_back(Room{"office", area, {2.0, -0.05}, {2.0, 1.6}, 0});
    Object& door = b.add(ObjectKind::Door, 0, {solid({1.5, -0.08, 0.0}, {2.5, -0.02, kDoorHeight}, Rgb{120, 80, 50})});
    b.s.rooms[0].door_object = door.id;
    furnish(b, 0, rng);
  } else if (preset == "office" || preset == "floor66" || preset == "weeks") {
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
    addWallX(b, -0.1, length + 0.1, corridor, north_doors, wall_colour);          // corridor, north side
    addWallX(b, -0.1, length + 0.1, corridor + depth + kWallThickness, {}, wall_colour);
    addWallX(b, -0.1, length + 0.1, -kWallThickness, south_doors, wall_colour);  // corridor, south side
    if (big) addWallX(b, -0.1, length + 0.1, -depth - 2 * kWallThickness, {}, wall_colour);
    addWallY(b, -0.1, big ? -depth - kWallThickness : 0.0, corridor + depth + kWallThickness, wall_colour);
    addWallY(b, length, big ? -depth - kWallThickness : 0.0, corridor + depth + kWallThickness, wall_colour);
    for (int i = 1; i < per_side; ++i) {
      addWallY(b, i * width - kWallThickness / 2, corridor + kWallThickness, corridor + depth + kWallThickness, wall_colour);
      if (big) addWallY(b, i * width - kWallThickness / 2, -depth - kWallThickness, -kWallThickness, wall_colour);
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
    throw UsageError("unknown simulator preset '" + preset + "' (use tiny, office, floor66, weeks or site)");
  }
  if (preset == "weeks") {
    // The people and the cart of the routines, at home and absent; applySchedule() places them.
    for (size_t r = 1; r < b.s.rooms.size(); ++r) {
      const Room& room = b.s.rooms[r];
      if (room.name != "office" && room.name != "kitchen") continue;
      const Eigen::Vector2d spot = room.name == "office" ? Eigen::Vector2d(room.area.max().x() - 0.6, room.inside_m.y() + 0.9)
                                                         : Eigen::Vector2d(room.area.min().x() + 0.6, room.inside_m.y() + 0.9);
      b.add(ObjectKind::Person, static_cast<int>(r), personAt(spot.x(), spot.y(), rng)).present = false;
    }
    const Room& corridor = b.s.rooms[0];
    const double y = corridor.area.min().y() + 0.35;
    b.add(ObjectKind::Cart, 0,
          {solid({0.6, y - 0.25, 0.0}, {1.5, y + 0.25, 0.95}, Rgb{40, 90, 170}),
           solid({0.6, y - 0.25, 0.95}, {0.7, y + 0.25, 1.1}, Rgb{60, 60, 60})})
        .present = false;
  }
  // Most doors stand open at first.
  for (Object& o : b.s.objects) {
    if (o.kind == ObjectKind::Door) o.present = preset == "weeks" || rng.chance(0.3);  // weeks: shut at home
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

std::vector<std::pair<uint32_t, EventKind>> applyChanges(SceneState& state, uint64_t seed, int session) {
  Rng rng(mix(seed, 1000 + static_cast<uint64_t>(session)));
  std::vector<std::pair<uint32_t, EventKind>> events;
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
          events.emplace_back(o.id, o.present ? EventKind::DoorClosed : EventKind::DoorOpened);
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
            events.emplace_back(o.id, EventKind::Moved);
          }
        }
        break;
      }
      case ObjectKind::Box:
        if (!room) break;
        if (o.present && rng.chance(0.08)) {
          o.present = false;
          events.emplace_back(o.id, EventKind::Removed);
        } else if (o.present && rng.chance(0.08)) {
          moveTo(o, spotIn(*room, rng, 0.4));
          events.emplace_back(o.id, EventKind::Moved);
        }
        break;
      case ObjectKind::Person:
      case ObjectKind::Robot: {
        const bool person = o.kind == ObjectKind::Person;
        const bool now = rng.chance(person ? 0.3 : 0.15);
        if (!now && !o.present) break;
        if (!now) {
          o.present = false;
          events.emplace_back(o.id, EventKind::Left);
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
        events.emplace_back(o.id, was ? EventKind::Moved : EventKind::Appeared);
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
                     randomColour(rng, 90, 230))};
    events.emplace_back(o.id, EventKind::Added);
    state.objects.push_back(std::move(o));
  }
  return events;
}

}  // namespace chronomap
