// The rhythmic building (preset "weeks"): every routine object's state as a function of the
// clock and of the day's exceptions, and the routines as scene.json states them.

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <string>

#include "chronomap/sim/scene.h"
#include "chronomap/core/error.h"
#include "internal.h"

namespace chronomap {

namespace {

using sim_detail::centerOf;
using sim_detail::mix;
using sim_detail::Rng;
using sim_detail::translate;

int roomIndex(const SceneState& s, const std::string& name) {
  for (size_t i = 0; i < s.rooms.size(); ++i) {
    if (s.rooms[i].name == name) return static_cast<int>(i);
  }
  return -2;
}

/// The routine objects of a "weeks" scene, found by room and kind.
struct WeeksObjects {
  uint32_t office_door = 0, kitchen_door = 0, meeting_door = 0;
  std::vector<uint32_t> office_chairs, meeting_chairs, kitchen_chairs;
  uint32_t worker = 0, cook = 0, cart = 0;
  bool found = false;
};

WeeksObjects weeksObjects(const SceneState& home) {
  WeeksObjects w;
  const int office = roomIndex(home, "office"), kitchen = roomIndex(home, "kitchen"),
            meeting = roomIndex(home, "meeting room");
  bool worker = false, cook = false, cart = false;
  for (const Object& o : home.objects) {
    if (o.kind == ObjectKind::Door) {
      if (o.room == office) w.office_door = o.id;
      if (o.room == kitchen) w.kitchen_door = o.id;
      if (o.room == meeting) w.meeting_door = o.id;
    } else if (o.kind == ObjectKind::Chair) {
      if (o.room == office) w.office_chairs.push_back(o.id);
      if (o.room == kitchen) w.kitchen_chairs.push_back(o.id);
      if (o.room == meeting) w.meeting_chairs.push_back(o.id);
    } else if (o.kind == ObjectKind::Person && o.room == office) {
      w.worker = o.id;
      worker = true;
    } else if (o.kind == ObjectKind::Person && o.room == kitchen) {
      w.cook = o.id;
      cook = true;
    } else if (o.kind == ObjectKind::Cart) {
      w.cart = o.id;
      cart = true;
    }
  }
  w.found = worker && cook && cart && office >= 0 && kitchen >= 0 && meeting >= 0;
  return w;
}

/// Moves `o` (at home in `home_o`) by `d` from its home position.
void placeFromHome(Object& o, const Object& home_o, const Eigen::Vector2d& d) {
  o.parts = home_o.parts;
  translate(o, Eigen::Vector3d(d.x(), d.y(), 0.0));
}

/// The unit direction in which a chair is pulled out: away from the table or desk it faces.
Eigen::Vector2d pullDirection(const Object& chair, const SceneState& home, ObjectKind furniture) {
  const Eigen::Vector2d c = centerOf(chair);
  double best = 1e9;
  Eigen::Vector2d dir(0.0, 1.0);
  for (const Object& o : home.objects) {
    if (o.kind != furniture || o.room != chair.room) continue;
    const Eigen::Vector2d d = c - centerOf(o);
    if (d.norm() < best) {
      best = d.norm();
      // Along y unless clearly along x: a corner chair (a tie) is pulled away from the long side.
      const bool along_y = std::abs(d.y()) + 0.1 >= std::abs(d.x());
      dir = along_y ? Eigen::Vector2d(0.0, d.y() > 0 ? 1.0 : -1.0) : Eigen::Vector2d(d.x() > 0 ? 1.0 : -1.0, 0.0);
    }
  }
  return dir;
}

bool between(double h, double from, double to) { return h >= from && h < to; }

}  // namespace

ScheduleDay scheduleDay(uint64_t seed, int day) {
  ScheduleDay d;
  d.weekday = ((day % 7) + 7) % 7;
  Rng rng(mix(seed, 9100 + static_cast<uint64_t>(day + 100000)));
  const bool weekday = d.weekday < 5;
  d.worker_away = weekday && rng.chance(0.15);
  d.weekend_visit = !weekday && rng.chance(0.2);
  d.meeting_cancelled = rng.chance(0.15);
  return d;
}

namespace {

std::vector<Routine> routinesOf(const WeeksObjects& w) {
  if (!w.found) return {};
  std::vector<uint32_t> office_things = w.office_chairs;
  office_things.push_back(w.worker);
  std::vector<uint32_t> lunch = w.kitchen_chairs;
  lunch.push_back(w.cook);
  return {
      {"office door", "open on weekdays 08:00-18:00 unless the worker is away, and 10:00-14:00 on weekend visits; "
                      "closed otherwise",
       {w.office_door}},
      {"office worker", "at the desk with the chair pulled out on weekdays 09:00-17:00 unless away, and 10:00-14:00 "
                        "on weekend visits",
       office_things},
      {"kitchen door", "open every day 07:00-22:00, closed at night", {w.kitchen_door}},
      {"meeting-room door", "open on weekdays 08:00-18:00, closed otherwise", {w.meeting_door}},
      {"meetings", "chairs pulled out from the table on Mondays and Wednesdays 10:00-11:30 and Tuesdays and "
                   "Thursdays 14:00-15:30, unless cancelled",
       w.meeting_chairs},
      {"lunch", "a person in the kitchen and its chairs pulled out on weekdays 12:00-13:30", lunch},
      {"cleaning", "a cleaning cart moving along the corridor on weekdays 19:00-20:30", {w.cart}},
  };
}

}  // namespace

std::vector<Routine> routinesOf(const SceneState& home) { return routinesOf(weeksObjects(home)); }

std::vector<ScheduledChange> applySchedule(SceneState& state, const SceneState& home, uint64_t seed, double time_s) {
  const WeeksObjects w = weeksObjects(home);
  if (!w.found) return {};
  const double since = time_s - kScheduleStart_s;
  const int day = static_cast<int>(std::floor(since / 86400.0));
  const double h = (since - 86400.0 * day) / 3600.0;
  const ScheduleDay d = scheduleDay(seed, day);
  const bool weekday = d.weekday < 5;
  const bool worker_in = (weekday && !d.worker_away && between(h, 9.0, 17.0)) || (d.weekend_visit && between(h, 10.0, 14.0));
  const bool office_open =
      (weekday && !d.worker_away && between(h, 8.0, 18.0)) || (d.weekend_visit && between(h, 10.0, 14.0));
  const bool meeting = weekday && !d.meeting_cancelled &&
                       (((d.weekday == 0 || d.weekday == 2) && between(h, 10.0, 11.5)) ||
                        ((d.weekday == 1 || d.weekday == 3) && between(h, 14.0, 15.5)));
  const bool lunch = weekday && between(h, 12.0, 13.5);
  const bool cleaning = weekday && between(h, 19.0, 20.5);

  // Which routine each object follows, for naming the changes.
  std::map<uint32_t, std::string> routine_of;
  for (const Routine& r : routinesOf(w)) {
    for (uint32_t id : r.objects) routine_of[id] = r.name;
  }
  SceneState next = home;
  Rng jitter(mix(seed, 9300 + static_cast<uint64_t>(day + 100000)));
  for (size_t i = 0; i < next.objects.size(); ++i) {
    Object& o = next.objects[i];
    const Object& at_home = home.objects[i];
    if (o.id == w.office_door) o.present = !office_open;  // a door present is a closed door
    if (o.id == w.kitchen_door) o.present = !between(h, 7.0, 22.0);
    if (o.id == w.meeting_door) o.present = !(weekday && between(h, 8.0, 18.0));
    if (o.id == w.worker) o.present = worker_in;
    if (o.id == w.cook) o.present = lunch;
    const bool office_chair = std::find(w.office_chairs.begin(), w.office_chairs.end(), o.id) != w.office_chairs.end();
    const bool kitchen_chair = std::find(w.kitchen_chairs.begin(), w.kitchen_chairs.end(), o.id) != w.kitchen_chairs.end();
    const bool meeting_chair = std::find(w.meeting_chairs.begin(), w.meeting_chairs.end(), o.id) != w.meeting_chairs.end();
    if (office_chair && worker_in) placeFromHome(o, at_home, 0.35 * pullDirection(at_home, home, ObjectKind::Desk));
    if (kitchen_chair && lunch) placeFromHome(o, at_home, 0.3 * pullDirection(at_home, home, ObjectKind::Table));
    if (meeting_chair) {
      // Each meeting leaves the chairs a little differently: a sideways jitter drawn per day.
      const double side = jitter.uniform(-0.12, 0.12);
      if (meeting) {
        placeFromHome(o, at_home, 0.4 * pullDirection(at_home, home, ObjectKind::Table) + Eigen::Vector2d(side, 0.0));
      }
    }
    if (o.id == w.cart) {
      o.present = cleaning;
      if (cleaning) {
        const Room& corridor = home.rooms[0];
        const double along = (h - 19.0) / 1.5 * (corridor.area.sizes().x() - 2.5);
        placeFromHome(o, at_home, Eigen::Vector2d(along, 0.0));
      }
    }
  }
  std::vector<ScheduledChange> changes = objectChanges(state, next);
  for (ScheduledChange& c : changes) {
    const auto r = routine_of.find(c.object);
    c.routine = r == routine_of.end() ? std::string() : r->second;
  }
  state = std::move(next);
  return changes;
}

std::vector<ScheduledChange> objectChanges(const SceneState& before_state, const SceneState& after) {
  // Before: presence and position of every object, by id.
  std::map<uint32_t, std::pair<bool, Eigen::Vector2d>> before;
  for (const Object& o : before_state.objects) before[o.id] = {o.present, centerOf(o)};
  std::vector<ScheduledChange> changes;
  for (const Object& o : after.objects) {
    const auto it = before.find(o.id);
    if (it == before.end()) continue;
    const auto [was_present, was_at] = it->second;
    ScheduledChange c;
    c.object = o.id;
    if (o.kind == ObjectKind::Door) {
      if (o.present == was_present) continue;
      c.kind = o.present ? EventKind::DoorClosed : EventKind::DoorOpened;
    } else if (o.present != was_present) {
      c.kind = o.present ? EventKind::Appeared : EventKind::Left;
    } else if (o.present && (centerOf(o) - was_at).norm() > 0.01) {
      c.kind = EventKind::Moved;
    } else {
      continue;
    }
    changes.push_back(c);
  }
  return changes;
}

// ---- Rare events ----

namespace {

Part rareBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Rgb c) {
  Part p;
  p.box = Eigen::AlignedBox3d(lo, hi);
  auto shade = [&](double f) {
    auto v = [f](uint8_t x) { return static_cast<uint8_t>(std::clamp(std::lround(x * f), 0L, 255L)); };
    return Rgb{v(c.r), v(c.g), v(c.b)};
  };
  p.face_colours = {shade(0.85), shade(0.9), shade(0.8), shade(0.95), shade(0.6), c};
  return p;
}

/// The objects of the rare events in a home scene from addRareObjects.
struct RareObjects {
  const Object* parcel = nullptr;
  const Object* shelf_item = nullptr;
  const Object* meeting_door = nullptr;
  const Object* kitchen_chair = nullptr;
  const Object* visitor = nullptr;  ///< the person who belongs to no routine
};

RareObjects rareObjects(const SceneState& home) {
  RareObjects r;
  const WeeksObjects w = weeksObjects(home);
  if (!w.found) throw UsageError("rare events need the weeks preset");
  for (const Object& o : home.objects) {
    if (o.id == w.meeting_door) r.meeting_door = &o;
    if (!w.kitchen_chairs.empty() && o.id == w.kitchen_chairs.front()) r.kitchen_chair = &o;
    if (o.kind == ObjectKind::Person && o.room == -1) r.visitor = &o;
  }
  // The two objects addRareObjects added, the last two.
  if (home.objects.size() >= 2 && home.objects.back().kind == ObjectKind::Box &&
      home.objects[home.objects.size() - 2].kind == ObjectKind::Box) {
    r.shelf_item = &home.objects[home.objects.size() - 2];
    r.parcel = &home.objects.back();
  }
  if (!r.parcel || !r.meeting_door || !r.kitchen_chair || !r.visitor) {
    throw UsageError("rare events need a weeks scene with addRareObjects applied");
  }
  return r;
}

}  // namespace

const char* describe(RareKind kind) {
  switch (kind) {
    case RareKind::Parcel: return "a parcel left in the corridor at night";
    case RareKind::ShelfItem: return "the box on the corridor shelf taken";
    case RareKind::DoorAtNight: return "the meeting-room door open at night";
    case RareKind::ChairInCorridor: return "a kitchen chair standing in the corridor";
    case RareKind::PersonAtNight: return "a person in the corridor at night";
  }
  return "rare event";
}

void addRareObjects(SceneState& home, uint64_t seed) {
  if (home.rooms.empty() || !weeksObjects(home).found) throw UsageError("rare events need the weeks preset");
  uint32_t next_id = 0;
  for (const Object& o : home.objects) next_id = std::max(next_id, o.id + 1);
  Rng rng(mix(seed, 9600));
  // A low shelf against the corridor's north wall near its east end, which never changes, with a
  // box on it; the patrol passes it every session.
  const Eigen::AlignedBox2d& corridor = home.rooms[0].area;
  const double x0 = corridor.max().x() - 1.3, y1 = corridor.max().y();
  Object shelf;
  shelf.id = next_id++;
  shelf.kind = ObjectKind::Shelf;
  shelf.room = 0;
  shelf.parts = {rareBox({x0, y1 - 0.35, 0.0}, {x0 + 0.9, y1, 0.9}, Rgb{110, 110, 120})};
  home.objects.push_back(shelf);
  const double x = x0 + 0.45 + rng.uniform(-0.15, 0.15);
  Object item;
  item.id = next_id++;
  item.kind = ObjectKind::Box;
  item.room = 0;
  item.parts = {rareBox({x - 0.18, y1 - 0.3, 0.9}, {x + 0.18, y1 - 0.05, 1.2}, Rgb{200, 60, 40})};
  home.objects.push_back(item);
  // The parcel, absent at home; rareEventOf's sessions place it.
  Object parcel;
  parcel.id = next_id++;
  parcel.kind = ObjectKind::Box;
  parcel.room = 0;
  parcel.parts = {rareBox({corridor.min().x() + 1.0, corridor.min().y() + 0.1, 0.0},
                          {corridor.min().x() + 1.5, corridor.min().y() + 0.5, 0.45}, Rgb{170, 130, 80})};
  parcel.present = false;
  home.objects.push_back(parcel);
}

std::optional<RareKind> rareEventOf(uint64_t seed, int session, const std::vector<double>& times_s) {
  const int sessions = static_cast<int>(times_s.size());
  const int first = sessions - sessions / 4;
  // 0 night (22:00-06:00), 1 day (07:00-22:00), -1 neither; a session has an event by chance.
  auto slot = [&](int s) {
    Rng rng(mix(seed, 9700 + static_cast<uint64_t>(s)));
    if (!rng.chance(0.75)) return -1;
    const double since = times_s[static_cast<size_t>(s)] - kScheduleStart_s;
    const double h = (since - 86400.0 * std::floor(since / 86400.0)) / 3600.0;
    if (h >= 22.0 || h < 6.0) return 0;
    return h >= 7.0 ? 1 : -1;
  };
  if (session < std::max(first, 1) || session >= sessions) return std::nullopt;
  const int mine = slot(session);
  if (mine < 0) return std::nullopt;
  // The kinds in turn: the n-th night (day) event of the last quarter takes the n-th night (day) kind.
  int turn = 0;
  for (int s = std::max(first, 1); s < session; ++s) turn += slot(s) == mine;
  static constexpr RareKind kNight[3] = {RareKind::Parcel, RareKind::DoorAtNight, RareKind::PersonAtNight};
  static constexpr RareKind kDay[2] = {RareKind::ShelfItem, RareKind::ChairInCorridor};
  return mine == 0 ? kNight[turn % 3] : kDay[turn % 2];
}

std::vector<uint32_t> applyRareEvent(SceneState& state, const SceneState& home, uint64_t seed, int session, RareKind kind) {
  const RareObjects r = rareObjects(home);
  Rng rng(mix(seed, 9800 + static_cast<uint64_t>(session)));
  const Eigen::AlignedBox2d& corridor = home.rooms[0].area;
  // Somewhere along the corridor, clear of its ends.
  const double along = rng.uniform(corridor.min().x() + 1.5, corridor.max().x() - 2.0);
  auto find = [&](uint32_t id) -> Object& {
    for (Object& o : state.objects) {
      if (o.id == id) return o;
    }
    throw UsageError("rare events: object " + std::to_string(id) + " missing");
  };
  auto placeAt = [&](Object& o, const Object& at_home, const Eigen::Vector2d& where) {
    o.parts = at_home.parts;
    const Eigen::Vector2d d = where - centerOf(at_home);
    translate(o, Eigen::Vector3d(d.x(), d.y(), 0.0));
    o.present = true;
  };
  switch (kind) {
    case RareKind::Parcel: {
      Object& o = find(r.parcel->id);
      placeAt(o, *r.parcel, {along, corridor.min().y() + 0.3});
      return {o.id};
    }
    case RareKind::ShelfItem: {
      Object& o = find(r.shelf_item->id);
      o.present = false;
      return {o.id};
    }
    case RareKind::DoorAtNight: {
      Object& o = find(r.meeting_door->id);
      o.present = false;  // a door present is a closed door
      return {o.id};
    }
    case RareKind::ChairInCorridor: {
      Object& o = find(r.kitchen_chair->id);
      placeAt(o, *r.kitchen_chair, {along, corridor.max().y() - 0.35});
      return {o.id};
    }
    case RareKind::PersonAtNight: {
      Object& o = find(r.visitor->id);
      placeAt(o, *r.visitor, {along, corridor.center().y() + 0.45});
      return {o.id};
    }
  }
  return {};
}

}  // namespace chronomap
