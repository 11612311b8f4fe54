// The rhythmic building's schedule (preset "weeks"): known states at known times.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/sim/scene.h"
#include "sim/internal.h"

namespace chronomap {
namespace {

constexpr uint64_t kSeed = 1;

/// The time `hour` o'clock (UTC) on day `day` of the schedule.
double scheduleTime(int day, double hour) { return kScheduleStart_s + 86400.0 * day + 3600.0 * hour; }

/// The routine objects by routine name.
std::map<std::string, std::vector<uint32_t>> routines(const SceneState& home) {
  std::map<std::string, std::vector<uint32_t>> out;
  for (const Routine& r : routinesOf(home)) out[r.name] = r.objects;
  return out;
}

const Object& object(const SceneState& s, uint32_t id) {
  for (const Object& o : s.objects) {
    if (o.id == id) return o;
  }
  throw std::runtime_error("no object " + std::to_string(id));
}

/// The first day from `from` whose exceptions satisfy `pred`.
template <class Pred>
int firstDay(int from, Pred pred) {
  for (int d = from; d < from + 400; ++d) {
    if (pred(scheduleDay(kSeed, d))) return d;
  }
  throw std::runtime_error("no such day");
}

TEST(Schedule, OnlyTheWeeksPresetHasRoutines) {
  EXPECT_TRUE(routinesOf(makeScene("office", kSeed)).empty());
  const auto r = routines(makeScene("weeks", kSeed));
  EXPECT_EQ(r.size(), 7u);
  EXPECT_EQ(r.at("meetings").size(), 6u);  // the meeting room's six chairs
  EXPECT_EQ(r.at("cleaning").size(), 1u);
}

TEST(Schedule, DaysFollowTheWeekAndExceptionsAreRare) {
  int away = 0, visits = 0, weekdays = 0, weekends = 0;
  for (int d = 0; d < 700; ++d) {
    const ScheduleDay s = scheduleDay(kSeed, d);
    EXPECT_EQ(s.weekday, d % 7);
    EXPECT_FALSE(s.worker_away && s.weekday >= 5);
    EXPECT_FALSE(s.weekend_visit && s.weekday < 5);
    (s.weekday < 5 ? weekdays : weekends)++;
    away += s.worker_away;
    visits += s.weekend_visit;
    EXPECT_EQ(scheduleDay(kSeed, d).worker_away, s.worker_away);  // the same every time asked
  }
  EXPECT_NEAR(static_cast<double>(away) / weekdays, 0.15, 0.05);
  EXPECT_NEAR(static_cast<double>(visits) / weekends, 0.2, 0.07);
}

TEST(Schedule, AtNightEveryDoorIsShutAndNobodyIsIn) {
  const SceneState home = makeScene("weeks", kSeed);
  const auto r = routines(home);
  for (int day = 0; day < 14; ++day) {
    SceneState s = home;
    applySchedule(s, home, kSeed, scheduleTime(day, 3.0));
    for (const char* door : {"office door", "kitchen door", "meeting-room door"}) {
      EXPECT_TRUE(object(s, r.at(door)[0]).present) << door << " on day " << day;  // present = shut
    }
    EXPECT_FALSE(object(s, r.at("office worker").back()).present);
    EXPECT_FALSE(object(s, r.at("lunch").back()).present);
    EXPECT_FALSE(object(s, r.at("cleaning")[0]).present);
    // Every chair at home.
    for (const char* routine : {"meetings", "lunch", "office worker"}) {
      for (uint32_t id : r.at(routine)) {
        const Object& o = object(s, id);
        if (o.kind != ObjectKind::Chair) continue;
        EXPECT_EQ(sim_detail::centerOf(o), sim_detail::centerOf(object(home, id)));
      }
    }
  }
}

TEST(Schedule, AWorkingDayMorningHasTheWorkerInAndTheMeetingOn) {
  const SceneState home = makeScene("weeks", kSeed);
  const auto r = routines(home);
  // A Monday with the worker in and the meeting on: at 10:30 both show.
  const int day = firstDay(0, [](const ScheduleDay& d) {
    return d.weekday == 0 && !d.worker_away && !d.meeting_cancelled;
  });
  SceneState s = home;
  const std::vector<ScheduledChange> changes = applySchedule(s, home, kSeed, scheduleTime(day, 10.5));
  EXPECT_FALSE(object(s, r.at("office door")[0]).present);       // open
  EXPECT_FALSE(object(s, r.at("meeting-room door")[0]).present);  // open
  EXPECT_TRUE(object(s, r.at("office worker").back()).present);
  for (uint32_t id : r.at("meetings")) {
    // Pulled out from the table by 0.4 m (and a sideways jitter of at most 0.12 m).
    const Eigen::Vector2d d = sim_detail::centerOf(object(s, id)) - sim_detail::centerOf(object(home, id));
    EXPECT_NEAR(std::abs(d.y()), 0.4, 1e-9);
    EXPECT_LE(std::abs(d.x()), 0.12 + 1e-9);
  }
  // The changes from home name their routines and cover exactly what moved or opened.
  std::set<std::string> named;
  for (const ScheduledChange& c : changes) named.insert(c.routine);
  EXPECT_EQ(named, (std::set<std::string>{"office door", "office worker", "kitchen door", "meeting-room door",
                                          "meetings"}));
  // The same time again changes nothing.
  EXPECT_TRUE(applySchedule(s, home, kSeed, scheduleTime(day, 10.5)).empty());
  // On a day the meeting is cancelled, the chairs stay in.
  const int cancelled = firstDay(0, [](const ScheduleDay& d) { return d.weekday == 2 && d.meeting_cancelled; });
  SceneState c = home;
  applySchedule(c, home, kSeed, scheduleTime(cancelled, 10.5));
  for (uint32_t id : r.at("meetings")) {
    EXPECT_EQ(sim_detail::centerOf(object(c, id)), sim_detail::centerOf(object(home, id)));
  }
}

TEST(Schedule, ExceptionsChangeTheDay) {
  const SceneState home = makeScene("weeks", kSeed);
  const auto r = routines(home);
  const int away = firstDay(0, [](const ScheduleDay& d) { return d.worker_away; });
  SceneState s = home;
  applySchedule(s, home, kSeed, scheduleTime(away, 11.0));
  EXPECT_TRUE(object(s, r.at("office door")[0]).present);  // shut all day
  EXPECT_FALSE(object(s, r.at("office worker").back()).present);
  const int visit = firstDay(0, [](const ScheduleDay& d) { return d.weekend_visit; });
  applySchedule(s, home, kSeed, scheduleTime(visit, 11.0));
  EXPECT_FALSE(object(s, r.at("office door")[0]).present);
  EXPECT_TRUE(object(s, r.at("office worker").back()).present);
  applySchedule(s, home, kSeed, scheduleTime(visit, 15.0));  // the visit ends at 14:00
  EXPECT_FALSE(object(s, r.at("office worker").back()).present);
}

TEST(Schedule, LunchAndCleaningKeepTheirHours) {
  const SceneState home = makeScene("weeks", kSeed);
  const auto r = routines(home);
  const int tuesday = firstDay(0, [](const ScheduleDay& d) { return d.weekday == 1; });
  SceneState s = home;
  applySchedule(s, home, kSeed, scheduleTime(tuesday, 12.5));
  EXPECT_TRUE(object(s, r.at("lunch").back()).present);
  applySchedule(s, home, kSeed, scheduleTime(tuesday, 13.6));
  EXPECT_FALSE(object(s, r.at("lunch").back()).present);
  // The cart moves along the corridor during the cleaning hour and a half.
  applySchedule(s, home, kSeed, scheduleTime(tuesday, 19.1));
  const Object& cart = object(s, r.at("cleaning")[0]);
  ASSERT_TRUE(cart.present);
  const double x_early = sim_detail::centerOf(cart).x();
  const auto later = applySchedule(s, home, kSeed, scheduleTime(tuesday, 20.4));
  ASSERT_EQ(later.size(), 1u);
  EXPECT_EQ(later[0].kind, EventKind::Moved);
  EXPECT_EQ(later[0].routine, "cleaning");
  EXPECT_GT(sim_detail::centerOf(object(s, r.at("cleaning")[0])).x(), x_early + 5.0);
  const auto gone = applySchedule(s, home, kSeed, scheduleTime(tuesday, 20.6));
  ASSERT_EQ(gone.size(), 1u);
  EXPECT_EQ(gone[0].kind, EventKind::Left);
  // Saturday: no lunch, no cleaning.
  const int saturday = firstDay(0, [](const ScheduleDay& d) { return d.weekday == 5; });
  applySchedule(s, home, kSeed, scheduleTime(saturday, 12.5));
  EXPECT_FALSE(object(s, r.at("lunch").back()).present);
  applySchedule(s, home, kSeed, scheduleTime(saturday, 19.5));
  EXPECT_FALSE(object(s, r.at("cleaning")[0]).present);
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

bool inCorridor(const SceneState& home, const Object& o) {
  return home.rooms[0].area.contains(sim_detail::centerOf(o));
}

TEST(Schedule, RareEventsChangeWhatTheyName) {
  const SceneState plain = makeScene("weeks", kSeed);
  SceneState home = plain;
  addRareObjects(home, kSeed);
  ASSERT_EQ(home.objects.size(), plain.objects.size() + 3);
  EXPECT_EQ(home.objects[home.objects.size() - 3].kind, ObjectKind::Shelf);
  const Object& item = home.objects[home.objects.size() - 2];
  const Object& parcel = home.objects.back();
  EXPECT_TRUE(item.present);  // on the corridor shelf, always
  EXPECT_FALSE(parcel.present);
  EXPECT_TRUE(inCorridor(home, item));
  const auto r = routines(home);
  struct Case {
    RareKind kind;
    uint32_t object;
    EventKind event;
    bool corridor;  // ends up in the corridor
  };
  const Case cases[] = {{RareKind::Parcel, parcel.id, EventKind::Appeared, true},
                        {RareKind::ShelfItem, item.id, EventKind::Left, false},
                        {RareKind::DoorAtNight, r.at("meeting-room door")[0], EventKind::DoorOpened, false},
                        {RareKind::ChairInCorridor, r.at("lunch")[0], EventKind::Moved, true},
                        {RareKind::PersonAtNight, 0, EventKind::Appeared, true}};
  for (const Case& c : cases) {
    SceneState s = home;
    applySchedule(s, home, kSeed, scheduleTime(2, 3.0));  // a Wednesday, 03:00: every door shut
    const SceneState before = s;
    const std::vector<uint32_t> changed = applyRareEvent(s, home, kSeed, 50, c.kind);
    const std::vector<ScheduledChange> changes = objectChanges(before, s);
    ASSERT_EQ(changes.size(), 1u) << describe(c.kind);
    ASSERT_EQ(changed, std::vector<uint32_t>{changes[0].object}) << describe(c.kind);
    if (c.object != 0) {
      EXPECT_EQ(changes[0].object, c.object) << describe(c.kind);
    }
    EXPECT_EQ(changes[0].kind, c.event) << describe(c.kind);
    const Object& o = object(s, changes[0].object);
    if (c.kind == RareKind::PersonAtNight) {
      EXPECT_EQ(o.kind, ObjectKind::Person);
    }
    if (c.corridor) {
      EXPECT_TRUE(inCorridor(home, o)) << describe(c.kind);
    }
    // The next session's schedule undoes it.
    SceneState next = s;
    const auto undone = applySchedule(next, home, kSeed, scheduleTime(2, 4.0));
    ASSERT_EQ(undone.size(), 1u) << describe(c.kind);
    EXPECT_EQ(undone[0].object, changes[0].object);
  }
  // The same seed and session place it the same; a plain weeks scene has no rare objects.
  SceneState a = home, b = home;
  applyRareEvent(a, home, kSeed, 50, RareKind::Parcel);
  applyRareEvent(b, home, kSeed, 50, RareKind::Parcel);
  EXPECT_EQ(sim_detail::centerOf(object(a, parcel.id)), sim_detail::centerOf(object(b, parcel.id)));
  SceneState no_rare = plain;
  EXPECT_THROW(applyRareEvent(no_rare, plain, kSeed, 50, RareKind::Parcel), UsageError);
  SceneState office = makeScene("office", kSeed);
  EXPECT_THROW(addRareObjects(office, kSeed), UsageError);
}

TEST(Schedule, RareEventsFallInTheLastQuarterAtFittingHours) {
  // Two sessions a day for four weeks at varied hours.
  std::vector<double> times;
  for (int i = 0; i < 56; ++i) times.push_back(scheduleTime(i / 2, std::fmod(5.3 * i, 12.0) + (i % 2 ? 12.0 : 0.0)));
  int night = 0, day = 0;
  std::set<RareKind> kinds;
  for (int s = 0; s < 56; ++s) {
    const auto k = rareEventOf(kSeed, s, times);
    EXPECT_EQ(k, rareEventOf(kSeed, s, times));  // deterministic
    if (!k) continue;
    EXPECT_GE(s, 42) << "session " << s;
    kinds.insert(*k);
    const double h = std::fmod((times[static_cast<size_t>(s)] - kScheduleStart_s) / 3600.0, 24.0);
    const bool at_night = *k == RareKind::Parcel || *k == RareKind::DoorAtNight || *k == RareKind::PersonAtNight;
    EXPECT_EQ(at_night, h >= 22.0 || h < 6.0) << describe(*k) << " at " << h;
    if (!at_night) {
      EXPECT_GE(h, 7.0);
    }
    (at_night ? night : day) += 1;
  }
  EXPECT_GE(night + day, 5);
  EXPECT_GE(kinds.size(), 4u);
}

}  // namespace
}  // namespace chronomap
