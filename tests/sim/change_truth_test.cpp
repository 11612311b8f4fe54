#include <gtest/gtest.h>

#include <cmath>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "builders.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/sim/change_truth.h"
#include "test_support.h"

namespace chronomap {
namespace {

constexpr int kTruthBase = kKeyOrigin - 16;


VoxelCounters occupied() {
  VoxelCounters c;
  c.hits = 4;
  c.length_m = 0.2f;  // P = 1 - exp(-20)
  return c;
}


// A 32^3 region observed free, with the given boxes (inclusive corners) occupied.
struct Box {
  int x0, y0, z0, x1, y1, z1;
};

SessionMap room(std::initializer_list<Box> boxes) {
  SessionMap m;
  for (int x = 0; x < 32; ++x) {
    for (int y = 0; y < 32; ++y) {
      for (int z = 0; z < 32; ++z) {
        bool in = false;
        for (const Box& b : boxes) in |= x >= b.x0 && x <= b.x1 && y >= b.y0 && y <= b.y1 && z >= b.z0 && z <= b.z1;
        m.add(test::at(x, y, z, kTruthBase), in ? occupied() : test::freeVoxel(0.5f));
      }
    }
  }
  return m;
}

ChangeEvent eventOf(const Box& b, uint32_t object, EventKind kind) {
  ChangeEvent e;
  e.object = object;
  e.object_kind = ObjectKind::Box;
  e.kind = kind;
  for (int x = b.x0; x <= b.x1; ++x) {
    for (int y = b.y0; y <= b.y1; ++y) {
      for (int z = b.z0; z <= b.z1; ++z) e.voxels.push_back(test::at(x, y, z, kTruthBase));
    }
  }
  return e;
}

ChangeScore score(const SessionMap& before, const SessionMap& after, const std::vector<ChangeEvent>& events) {
  const DiffMap d = diff(before, after);
  return scoreChanges(d, segment(d), events, before, after);
}

TEST(ChangeTruth, AnAppearedBoxIsFoundAndAStrayVoxelIsFalse) {
  const Box table{4, 4, 4, 7, 7, 7};   // 64 voxels
  const Box stray{20, 20, 20, 22, 22, 22};  // 27 voxels, no event
  const SessionMap before = room({});
  const SessionMap after = room({table, stray});
  const ChangeScore s = score(before, after, {eventOf(table, 3, EventKind::Appeared)});
  EXPECT_EQ(s.events, 1u);
  EXPECT_EQ(s.events_observable, 1u);
  EXPECT_EQ(s.events_found, 1u);
  EXPECT_TRUE(s.missed_events.empty());
  EXPECT_EQ(s.components, 2u);
  EXPECT_EQ(s.false_components, 1u);
  EXPECT_EQ(s.changed_voxels, 64u + 27u);
  EXPECT_EQ(s.true_changed_voxels, 64u);
  EXPECT_EQ(s.truth_voxels, 64u);
  EXPECT_EQ(s.truth_voxels_found, 64u);
  EXPECT_DOUBLE_EQ(s.precision(), 64.0 / 91.0);
  EXPECT_DOUBLE_EQ(s.recall(), 1.0);
}

TEST(ChangeTruth, AnUnseenChangeIsMissedAndNamed) {
  // The event's voxels are observed in both sessions but did not change in the maps (as when
  // the diff filters it away): it is observable, not found, and named.
  const Box chair{10, 10, 10, 12, 12, 12};
  const SessionMap before = room({chair});
  const SessionMap after = room({chair});
  ChangeEvent e = eventOf(chair, 17, EventKind::Moved);
  e.from_session = 2;
  const ChangeScore s = score(before, after, {e});
  EXPECT_EQ(s.events_observable, 1u);
  EXPECT_EQ(s.events_found, 0u);
  ASSERT_EQ(s.missed_events.size(), 1u);
  EXPECT_EQ(s.missed_events[0], "box 17 moved (session 2 -> 3, 27 voxels observed)");
  EXPECT_EQ(s.changed_voxels, 0u);
  EXPECT_DOUBLE_EQ(s.precision(), 1.0);
  EXPECT_DOUBLE_EQ(s.recall(), 0.0);
}

TEST(ChangeTruth, EventsOutsideTheObservedSpaceDoNotCount) {
  // 19 voxels known (below the default minimum of 20), the rest outside the observed region.
  ChangeEvent e;
  e.object_kind = ObjectKind::Door;
  e.kind = EventKind::DoorOpened;
  for (int i = 0; i < 19; ++i) e.voxels.push_back(test::at(i, 0, 0, kTruthBase));
  for (int i = 0; i < 40; ++i) e.voxels.push_back(test::at(i, 40, 0, kTruthBase));
  const SessionMap m = room({});
  ChangeScore s = score(m, m, {e});
  EXPECT_EQ(s.events_observable, 0u);
  EXPECT_TRUE(s.missed_events.empty());
  EXPECT_EQ(s.truth_voxels, 19u);
  // Sums add up, missed events included.
  ChangeScore twice = s;
  e.voxels.push_back(test::at(19, 0, 0, kTruthBase));
  twice += score(m, m, {e});
  EXPECT_EQ(twice.events, 2u);
  EXPECT_EQ(twice.events_observable, 1u);
  EXPECT_EQ(twice.missed_events.size(), 1u);
  EXPECT_EQ(twice.truth_voxels, 39u);
}

TEST(ChangeTruth, KindsReadBackAsTheyAreWritten) {
  for (EventKind k : {EventKind::DoorOpened, EventKind::DoorClosed, EventKind::Moved, EventKind::Added,
                      EventKind::Removed, EventKind::Appeared, EventKind::Left}) {
    EXPECT_EQ(parseEventKind(toString(k)), k) << toString(k);
  }
  EXPECT_STREQ(toString(EventKind::DoorOpened), "door_opened");
  EXPECT_STREQ(toString(EventKind::Left), "left");
  EXPECT_THROW(parseEventKind("teleported"), FormatError);
  EXPECT_THROW(parseEventKind(""), FormatError);
  for (ObjectKind k : {ObjectKind::Floor, ObjectKind::Wall, ObjectKind::Door, ObjectKind::Desk, ObjectKind::Chair,
                       ObjectKind::Shelf, ObjectKind::Table, ObjectKind::Box, ObjectKind::Person, ObjectKind::Robot}) {
    EXPECT_EQ(parseObjectKind(toString(k)), k) << toString(k);
  }
  EXPECT_THROW(parseObjectKind("sofa"), FormatError);
}

TEST(ChangeTruth, ReadsTheEventsOfASceneAndRejectsUnknownKinds) {
  test::TempDir tmp;
  const auto write = [&](const std::string& kind) {
    const std::string text = R"({"events": [{"from_session": 1, "to_session": 2, "object": 7, "object_kind": "chair",
                                 "kind": ")" + kind + R"(", "voxel_count": 1, "voxels": [[1, 2, 3]]}]})";
    writeFileAtomic(tmp / "scene.json", std::vector<uint8_t>(text.begin(), text.end()));
    return tmp / "scene.json";
  };
  const std::vector<ChangeEvent> events = readTruthEvents(write("door_closed"));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].from_session, 1u);
  EXPECT_EQ(events[0].object, 7u);
  EXPECT_EQ(events[0].object_kind, ObjectKind::Chair);
  EXPECT_EQ(events[0].kind, EventKind::DoorClosed);
  EXPECT_EQ(events[0].voxels, (std::vector<VoxelKey>{VoxelKey{1, 2, 3}}));
  try {
    readTruthEvents(write("vanished"));
    FAIL() << "an unknown kind was read";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("scene.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'vanished'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace chronomap
