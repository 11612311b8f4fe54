#pragma once
/// @file
/// The simulated building's scene: objects made of boxes in rooms, generated from a seed, and
/// the change events between sessions.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/key.h"
#include "chronomap/core/counters.h"

namespace chronomap {

/// What an object is; change processes act by kind.
enum class ObjectKind : uint8_t { Floor, Wall, Door, Desk, Chair, Shelf, Table, Box, Person, Robot, Cart };
/// "floor", "wall", "door", ...
const char* toString(ObjectKind kind);
/// The kind toString() names. @throw FormatError for an unknown name.
ObjectKind parseObjectKind(const std::string& name);

/// One axis-aligned box of an object with a colour per face (-x, +x, -y, +y, -z, +z).
struct Part {
  Eigen::AlignedBox3d box;
  std::array<Rgb, 6> face_colours;
  /// Bit f set: face f (same order) is shiny (varnish, metal), which an active depth camera
  /// loses or measures off (DepthCameraModel); the ideal sensor ignores it. Set by kind when the
  /// scene is built: desk tops, table tops, robots and the cleaning cart's handle.
  uint8_t shiny_faces = 0;
};

/// An object of the scene. Its parts are in world coordinates for the current state.
struct Object {
  uint32_t id = 0;
  ObjectKind kind = ObjectKind::Box;
  int room = -1;  ///< index into SceneState::rooms, -1 for the corridor or the building
  bool present = true;
  std::vector<Part> parts;
};

/// A room's floor area (z = 0) and its door.
struct Room {
  std::string name;           ///< "office 3", "kitchen", "meeting room", "corridor"
  Eigen::AlignedBox2d area;   ///< inside the walls
  Eigen::Vector2d door_m;     ///< centre of the door opening, on the wall to the corridor
  Eigen::Vector2d inside_m;   ///< where the robot stands to look around
  uint32_t door_object = 0;   ///< id of the door
};

/// The state of the building during one session.
struct SceneState {
  std::vector<Object> objects;
  std::vector<Room> rooms;
  Eigen::AlignedBox3d bounds;
};

/// What happened to an object between two sessions.
enum class EventKind : uint8_t { DoorOpened, DoorClosed, Moved, Added, Removed, Appeared, Left };
/// "door_opened", "door_closed", "moved", "added", "removed", "appeared", "left" (as in scene.json).
const char* toString(EventKind kind);
/// The kind toString() names. @throw FormatError for an unknown name.
EventKind parseEventKind(const std::string& name);

/// One change between sessions `from_session` and `from_session + 1`, with the voxels of the
/// ground truth it changes: what simulate() writes into scene.json and readTruthEvents() reads.
struct ChangeEvent {
  uint32_t from_session = 0;
  uint32_t object = 0;
  ObjectKind object_kind = ObjectKind::Box;
  EventKind kind = EventKind::Moved;
  std::vector<VoxelKey> voxels;  ///< truth voxels whose occupancy differs because of it
  /// Why it happened (scene.json "cause"): "random" (the random processes), "routine" (the
  /// rhythmic building's schedule), "rare" (a rare event, SimulationSettings::rare_events) or
  /// "after_rare" (the schedule undoing a rare event at the next session). Empty in scenes
  /// written before causes were recorded.
  std::string cause;
  std::string routine;  ///< the routine or the rare event, in words ("meetings", "a parcel left ...")
};

/// A routine of the rhythmic building (preset "weeks"): objects whose state follows the clock.
struct Routine {
  std::string name;               ///< "office door", "office worker", "meetings", "lunch", "cleaning", ...
  std::string rule;               ///< when, in words (scene.json states it)
  std::vector<uint32_t> objects;  ///< the objects it moves, opens or brings
};
/// The day-level exceptions of the rhythmic building's schedule, day 0 being the first Monday.
struct ScheduleDay {
  int weekday = 0;                 ///< 0 Monday .. 6 Sunday
  bool worker_away = false;        ///< a weekday the office worker does not come (door stays shut)
  bool weekend_visit = false;      ///< a weekend day the worker comes in from 10:00 to 14:00
  bool meeting_cancelled = false;  ///< the day's meeting does not take place
};
/// Midnight (UTC) of the rhythmic building's first day, a Monday: 2012-03-05.
inline constexpr double kScheduleStart_s = 1330905600.0;
/// The exceptions of day `day` (from kScheduleStart_s) for `seed`.
ScheduleDay scheduleDay(uint64_t seed, int day);
/// The routines of a "weeks" scene (its first state, from makeScene); empty for other presets.
std::vector<Routine> routinesOf(const SceneState& home);
/// One object's change between two states and the routine that made it.
struct ScheduledChange {
  uint32_t object = 0;
  EventKind kind = EventKind::Moved;
  std::string routine;
  std::string cause = "routine";  ///< "routine", "rare" or "after_rare" (see ChangeEvent::cause)
};
/// Sets `state` to the rhythmic building's true state at `time_s`: every routine object placed
/// from `home` (makeScene("weeks", seed)) by the clock and the day's exceptions, everything else
/// as at home. Returns the objects that differ from what `state` held before, with the routine
/// responsible.
std::vector<ScheduledChange> applySchedule(SceneState& state, const SceneState& home, uint64_t seed, double time_s);

/// The changes of every object from `before` to `after` (the same scene in two states): a door
/// opened or closed, an object that appeared, left or moved by more than a centimetre.
std::vector<ScheduledChange> objectChanges(const SceneState& before, const SceneState& after);

/// The rare events of the rhythmic building (SimulationSettings::rare_events), each lasting one
/// session on top of the schedule: a parcel left in the corridor at night, the box on the
/// corridor shelf taken (it never moves otherwise), the meeting-room door open at night, a kitchen
/// chair standing in the corridor, a person in the corridor at night.
enum class RareKind : uint8_t { Parcel, ShelfItem, DoorAtNight, ChairInCorridor, PersonAtNight };
/// "parcel left in the corridor at night", ...
const char* describe(RareKind kind);
/// Adds the objects the rare events need to a "weeks" home scene, with new ids after every other
/// object: a shelf against the corridor's north wall and the box on it (present), and the parcel
/// (absent). @throw UsageError for a scene that is not the weeks preset's.
void addRareObjects(SceneState& home, uint64_t seed);
/// The rare event of session `session` (of the sessions at `times_s`), if any: one in most
/// sessions of the last quarter (the test week of four), of a kind that fits the hour (the night
/// kinds between 22:00 and 06:00, the others between 07:00 and 22:00), each kind in turn.
std::optional<RareKind> rareEventOf(uint64_t seed, int session, const std::vector<double>& times_s);
/// Applies a rare event to a state the schedule made (on a home from addRareObjects); returns
/// the objects it changed.
std::vector<uint32_t> applyRareEvent(SceneState& state, const SceneState& home, uint64_t seed, int session, RareKind kind);

/// The site preset ("site"): kSiteFloors floors, each a floor66 building of its own (drawn from
/// siteFloorSeed()), stacked kSiteFloorHeight_m apart. Each floor keeps its own state and change
/// processes in its own frame (siteFloor(), applyChanges()); stackFloors() puts them together.
inline constexpr int kSiteFloors = 3;
/// Height from one floor's walking surface to the next one's.
inline constexpr double kSiteFloorHeight_m = 3.0;
/// An object of floor f has id f * kSiteIdStride + its id on the floor.
inline constexpr uint32_t kSiteIdStride = 10000;
/// The seed of floor `floor` of the site: its building, its changes and its patrol.
uint64_t siteFloorSeed(uint64_t seed, int floor);
/// Floor `floor` of the site in its first session's state, in its own frame (walking surface at
/// z = 0 as in floor66): makeScene("floor66", siteFloorSeed(seed, floor)).
SceneState siteFloor(uint64_t seed, int floor);
/// The site's floors as one scene: floor f raised by f * kSiteFloorHeight_m, its object ids
/// offset by f * kSiteIdStride, its rooms named "office 3 (floor 1)" and indexed after the floors
/// below.
SceneState stackFloors(const std::vector<SceneState>& floors);

/// The building of a preset in its first session's state.
/// @throw UsageError for an unknown preset.
SceneState makeScene(const std::string& preset, uint64_t seed);
/// Applies one session's change processes to `state`; returns the changed object ids with
/// their event kinds. A session may have no change at all.
std::vector<std::pair<uint32_t, EventKind>> applyChanges(SceneState& state, uint64_t seed, int session);

}  // namespace chronomap
