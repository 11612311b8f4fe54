// The writer: simulate() runs the sessions and writes their TUM folders, the truth and scene.json.
#include "chronomap/sim/building.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/core/parallel.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "internal.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

using sim_detail::centerOf;
using sim_detail::kCameraHeight;
using sim_detail::kCameraPitchDeg;
using sim_detail::mix;
using sim_detail::Rng;

struct PresetPlan {
  int sessions;
  double days;
};

PresetPlan presetPlan(const std::string& preset) {
  if (preset == "tiny") return {3, 2};
  if (preset == "office") return {6, 4};
  if (preset == "weeks") return {56, 28};
  if (preset == "site") return {365, 365};
  return {66, 45};
}

std::string poseLine(double stamp, const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  char buf[256];
  std::snprintf(buf, sizeof buf, "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", stamp, T.translation().x(),
                T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

// A file inside the staging folder: written plainly, without writeFileAtomic's temporary, flush
// to disk and scan of the folder for stale temporaries (which cost more than rendering on a
// session of hundreds of frames), since nothing is visible until the whole folder is moved into
// place.
void writeStaged(const fs::path& path, const uint8_t* data, size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw IoError(path.string() + ": cannot create (" + std::strerror(errno) + ")");
  const bool written = std::fwrite(data, 1, size, f) == size;
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed) throw IoError(path.string() + ": write failed (" + std::strerror(errno) + ")");
}

void writeText(const fs::path& path, const std::string& text) {
  writeStaged(path, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

// scene.json's change events, spooled to a file: each one as nlohmann::json::dump(1) would
// write it as an element of the top-level "events" array (its lines indented by two more), so
// that the spliced file is byte for byte scene.dump(1) with the events in it.
class EventSpool {
 public:
  static constexpr const char* kMarker = "@@chronomap events@@";

  explicit EventSpool(fs::path path) : path_(std::move(path)), file_(std::fopen(path_.c_str(), "wb+")) {
    if (!file_) throw IoError(path_.string() + ": cannot create (" + std::strerror(errno) + ")");
  }
  ~EventSpool() {
    if (file_) std::fclose(file_);
    std::error_code ignored;
    fs::remove(path_, ignored);
  }
  EventSpool(const EventSpool&) = delete;
  EventSpool& operator=(const EventSpool&) = delete;

  void add(const nlohmann::json& event) {
    std::string text = count_ == 0 ? "\n  " : ",\n  ";
    const std::string element = event.dump(1);
    for (const char c : element) {
      text += c;
      if (c == '\n') text += "  ";
    }
    put(text.data(), text.size());
    ++count_;
  }

  // Writes `scene` (scene.dump(1) with "events" set to kMarker) with the events in place of
  // the marker, and removes the spool.
  void writeScene(const fs::path& out, const std::string& scene) {
    const std::string marker = std::string("\"") + kMarker + "\"";
    const size_t at = scene.find(marker);
    if (at == std::string::npos) throw IoError(out.string() + ": the events' place is missing");
    std::FILE* f = std::fopen(out.c_str(), "wb");
    if (!f) throw IoError(out.string() + ": cannot create (" + std::strerror(errno) + ")");
    bool ok = std::fwrite(scene.data(), 1, at, f) == at;
    if (count_ == 0) {
      ok = ok && std::fputs("[]", f) >= 0;
    } else {
      ok = ok && std::fputc('[', f) != EOF && std::fflush(file_) == 0 && std::fseek(file_, 0, SEEK_SET) == 0;
      std::vector<char> buffer(1 << 20);
      size_t n = 0;
      while (ok && (n = std::fread(buffer.data(), 1, buffer.size(), file_)) > 0) ok = std::fwrite(buffer.data(), 1, n, f) == n;
      ok = ok && !std::ferror(file_) && std::fputs("\n ]", f) >= 0;
    }
    const size_t rest = scene.size() - at - marker.size();
    ok = ok && std::fwrite(scene.data() + at + marker.size(), 1, rest, f) == rest;
    ok = std::fclose(f) == 0 && ok;
    if (!ok) throw IoError(out.string() + ": write failed (" + std::strerror(errno) + ")");
    std::fclose(file_);
    file_ = nullptr;
    fs::remove(path_);
  }

 private:
  void put(const char* data, size_t size) {
    if (std::fwrite(data, 1, size, file_) != size) {
      throw IoError(path_.string() + ": write failed (" + std::strerror(errno) + ")");
    }
  }
  fs::path path_;
  std::FILE* file_;
  size_t count_ = 0;
};

template <class Image>
void writePngStaged(const fs::path& path, const Image& image) {
  const std::vector<uint8_t> bytes = encodePng(image);
  writeStaged(path, bytes.data(), bytes.size());
}

nlohmann::json objectsJson(const SceneState& state) {
  nlohmann::json objects = nlohmann::json::array();
  for (const Object& o : state.objects) {
    if (!o.present) continue;
    nlohmann::json parts = nlohmann::json::array();
    for (const Part& p : o.parts) {
      parts.push_back({{"min", {p.box.min().x(), p.box.min().y(), p.box.min().z()}},
                       {"max", {p.box.max().x(), p.box.max().y(), p.box.max().z()}},
                       {"color", {p.face_colours[5].r, p.face_colours[5].g, p.face_colours[5].b}}});
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

void checkSettings(const SimulationSettings& settings, int sessions) {
  if (settings.sessions < 0 || sessions > 1000) throw UsageError("--sessions must lie between 1 and 1000");
  if (!(settings.resolution_scale >= 0.1 && settings.resolution_scale <= 1.0)) {
    throw UsageError("--resolution-scale must lie between 0.1 and 1");
  }
  if (!(settings.noise_per_m2 >= 0.0) || !(settings.localisation_offset_m >= 0.0) ||
      !(settings.localisation_yaw_deg >= 0.0) || !(settings.drift_per_frame_m >= 0.0)) {
    throw UsageError("noise and localisation errors must be non-negative");
  }
  if (settings.preset == "site" && (settings.floors < 1 || settings.floors > 50)) {
    throw UsageError("--floors must lie between 1 and 50");
  }
  if (settings.lighting != "fixed" && settings.lighting != "daylight") {
    throw UsageError("--lighting must be fixed or daylight, not '" + settings.lighting + "'");
  }
  parseSensorKind(settings.sensor);
}

struct SessionTimes {
  std::vector<double> times, hours;
};

// Session times: 2 or 3 sessions on a recording day, at different hours, a day or two apart;
// for the rhythmic building ("weeks"), two a day every day from its first Monday, one in the
// morning half of the day and one in the evening half, at any hour, nights included.
SessionTimes sessionTimes(const SimulationSettings& settings, const PresetPlan& plan, int sessions) {
  Rng time_rng(mix(settings.seed, 77));
  std::vector<double> times, hours;
  const bool rhythmic = settings.preset == "weeks";
  const bool site = settings.preset == "site";
  const double start = rhythmic || site ? kScheduleStart_s : 1330560000.0;  // 2012-03-05 / 2012-03-01 00:00 UTC
  double day = 0.0;
  // The site: one patrol a night, starting between 22:00 and 03:00, every night.
  while (site && static_cast<int>(times.size()) < sessions) {
    const double h = time_rng.uniform(22.0, 27.0);
    hours.push_back(h >= 24.0 ? h - 24.0 : h);
    times.push_back(start + 86400.0 * static_cast<double>(times.size()) + 3600.0 * h);
  }
  while (rhythmic && static_cast<int>(times.size()) < sessions) {
    const double h = time_rng.uniform(0.0, 12.0) + (times.size() % 2 == 1 ? 12.0 : 0.0);
    hours.push_back(h);
    times.push_back(start + 86400.0 * static_cast<double>(times.size() / 2) + 3600.0 * h);
  }
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
  return {std::move(times), std::move(hours)};
}

// The repainted object: the first table no routine moves (else the first such desk).
uint32_t repaintObject(const SceneState& home, const SimulationSettings& settings, int sessions) {
  std::vector<uint32_t> routine_objects;
  for (const Routine& r : routinesOf(home)) {
    routine_objects.insert(routine_objects.end(), r.objects.begin(), r.objects.end());
  }
  uint32_t repaint_object = 0;
  bool found = false;
  for (const ObjectKind kind : {ObjectKind::Table, ObjectKind::Desk}) {
    for (const Object& o : home.objects) {
      if (found || o.kind != kind || !o.present) continue;
      if (std::find(routine_objects.begin(), routine_objects.end(), o.id) != routine_objects.end()) continue;
      repaint_object = o.id;
      found = true;
    }
  }
  if (!found) throw UsageError("--repaint: the " + settings.preset + " preset has no table or desk to repaint");
  if (sessions < 2) throw UsageError("--repaint needs at least 2 sessions");
  return repaint_object;
}

// What every session is rendered with.
struct Rig {
  const KeyGrid& grid;
  const Camera& camera;
  const SensorModel& sensor;
};

// The sessions one after the other, with the scene state, truth and scene.json's parts that
// carry from each session to the next.
class Simulation {
 public:
  Simulation(const SimulationSettings& settings, const Rig& rig, const fs::path& out, const fs::path& root,
             const SessionTimes& times, SceneState initial, int sessions)
      : settings_(settings), rig_(rig), out_(out), root_(root), times_(times.times), hours_(times.hours),
        rhythmic_(settings.preset == "weeks"), site_(settings.preset == "site"),
        // The change events go to a file in the staging folder as they come, already formatted
        // as elements of scene.json's "events" (their voxels make them most of scene.json: about
        // 4 MB a night on the site, far more than memory should hold for a year); writeScene()
        // splices them.
        events_(root / ".events.tmp"), state_(std::move(initial)) {
    if (settings.rare_events) {
      if (!rhythmic_) throw UsageError("--rare-events needs the weeks preset");
      addRareObjects(state_, settings.seed);
    }
    home_ = state_;
    // The site's floors, each in its own frame with its own change processes and patrol.
    for (int f = 0; site_ && f < settings.floors; ++f) floors_.push_back(siteFloor(settings.seed, f));
    daylight_.building = state_.bounds;
    use_daylight_ = settings.lighting == "daylight";
    // Repainted from session repaint_at_ on.
    repaint_at_ = settings.repaint ? std::max(1, sessions - sessions / 4) : -1;
    if (settings.repaint) repaint_object_ = repaintObject(home_, settings, sessions);
  }

  void session(int s);
  // Writes scene.json (with the spooled events) into the staging folder.
  void writeScene();
  SimulationSummary& summary() { return summary_; }

 private:
  std::vector<ScheduledChange> changesOf(int s);
  std::vector<ScheduledChange> scheduleChanges(int s);
  void repaint(int s);
  void addEvents(int s, const std::vector<ScheduledChange>& changes, const std::vector<VoxelKey>& truth);
  sim_detail::Patrol patrolOf(int s, nlohmann::json& floors_json) const;
  void writeFrames(int s, const fs::path& dir, const sim_detail::Patrol& patrol) const;
  void writeTruth(int s, const std::vector<VoxelKey>& truth) const;
  nlohmann::json scheduleJson() const;
  nlohmann::json lightingJson() const;

  const SimulationSettings& settings_;
  const Rig& rig_;
  const fs::path& out_;
  const fs::path& root_;
  const std::vector<double>& times_;
  const std::vector<double>& hours_;
  const bool rhythmic_;
  const bool site_;
  SimulationSummary summary_;
  nlohmann::json sessions_json_ = nlohmann::json::array();
  EventSpool events_;
  std::vector<VoxelKey> previous_truth_;
  SceneState previous_state_;
  SceneState state_;
  SceneState home_;
  std::vector<SceneState> floors_;
  Daylight daylight_;
  bool use_daylight_ = false;
  int repaint_at_ = -1;
  uint32_t repaint_object_ = 0;
  nlohmann::json repaints_json_ = nlohmann::json::array();
  std::vector<uint32_t> rare_before_;  // the objects the previous session's rare event changed
  nlohmann::json rare_json_ = nlohmann::json::array();
};

// Each change with its cause: a routine of the schedule, or the random processes.
std::vector<ScheduledChange> Simulation::changesOf(int s) {
  std::vector<ScheduledChange> changes;
  if (rhythmic_) {
    changes = scheduleChanges(s);
    if (s == 0) changes.clear();  // the first session's state is where the history starts
  } else if (site_) {
    for (size_t f = 0; f < floors_.size() && s > 0; ++f) {
      for (const auto& [id, kind] : applyChanges(floors_[f], siteFloorSeed(settings_.seed, static_cast<int>(f)), s)) {
        changes.push_back({static_cast<uint32_t>(f) * kSiteIdStride + id, kind, {}});
      }
    }
    state_ = stackFloors(floors_);
  } else if (s > 0) {
    for (const auto& [id, kind] : applyChanges(state_, settings_.seed, s)) changes.push_back({id, kind, {}});
  }
  return changes;
}

std::vector<ScheduledChange> Simulation::scheduleChanges(int s) {
  const SceneState before = state_;
  std::vector<ScheduledChange> changes =
      applySchedule(state_, home_, settings_.seed, times_[static_cast<size_t>(s)]);
  if (!settings_.rare_events) return changes;
  // The schedule, then the session's rare event on top; each change labelled with its cause.
  std::map<uint32_t, std::string> routine_of;
  for (const Routine& r : routinesOf(home_)) {
    for (uint32_t id : r.objects) routine_of[id] = r.name;
  }
  std::vector<uint32_t> rare_now;
  const auto rare = rareEventOf(settings_.seed, s, times_);
  if (rare) {
    rare_now = applyRareEvent(state_, home_, settings_.seed, s, *rare);
    rare_json_.push_back({{"session", s}, {"what", describe(*rare)}, {"objects", rare_now}});
  }
  changes = objectChanges(before, state_);
  for (ScheduledChange& c : changes) {
    const auto in = [&](const std::vector<uint32_t>& ids) {
      return std::find(ids.begin(), ids.end(), c.object) != ids.end();
    };
    const auto r = routine_of.find(c.object);
    c.routine = r == routine_of.end() ? std::string() : r->second;
    if (in(rare_now)) {
      c.cause = "rare";
      c.routine = describe(*rare);
    } else if (in(rare_before_)) {
      c.cause = "after_rare";
    }
  }
  rare_before_ = rare_now;
  return changes;
}

// Applied after the session's changes, so that a schedule restoring objects from home cannot
// undo it.
void Simulation::repaint(int s) {
  const Rgb repaint_colour{196, 52, 44};  // a red unlike any face colour of the presets
  for (Object& o : state_.objects) {
    if (o.id != repaint_object_) continue;
    if (s == repaint_at_) {
      nlohmann::json voxels = nlohmann::json::array();
      for (const VoxelKey& k : objectVoxels(o, rig_.grid)) voxels.push_back({k.x, k.y, k.z});
      const Rgb was = o.parts.front().face_colours[5];
      repaints_json_.push_back({{"from_session", s - 1},
                                {"to_session", s},
                                {"object", o.id},
                                {"object_kind", toString(o.kind)},
                                {"from", {was.r, was.g, was.b}},
                                {"to", {repaint_colour.r, repaint_colour.g, repaint_colour.b}},
                                {"voxel_count", voxels.size()},
                                {"voxels", voxels}});
    }
    for (Part& part : o.parts) part.face_colours.fill(repaint_colour);
  }
}

// Change events with the truth voxels each one changes.
void Simulation::addEvents(int s, const std::vector<ScheduledChange>& changes, const std::vector<VoxelKey>& truth) {
  for (const auto& [id, kind, routine, cause] : changes) {
    ChangeEvent e = sim_detail::changeEvent(id, kind, previous_state_, state_, previous_truth_, truth, rig_.grid);
    e.from_session = static_cast<uint32_t>(s - 1);
    if (e.voxels.empty()) continue;  // hidden by other objects: nothing a map could see
    nlohmann::json voxels = nlohmann::json::array();
    for (const VoxelKey& k : e.voxels) voxels.push_back({k.x, k.y, k.z});
    events_.add({{"from_session", e.from_session},
                 {"to_session", s},
                 {"object", e.object},
                 {"object_kind", toString(e.object_kind)},
                 {"kind", toString(e.kind)},
                 {"cause", rhythmic_ ? cause : "random"},
                 {"routine", routine},
                 {"voxel_count", e.voxels.size()},
                 {"voxels", voxels}});
    ++summary_.events;
  }
}

// The patrol, true and estimated poses; on the site, each floor's part goes into floors_json.
sim_detail::Patrol Simulation::patrolOf(int s, nlohmann::json& floors_json) const {
  if (!site_) return sim_detail::patrolSession(state_, settings_, s);
  // One patrol per floor, one after the other, each with its own localisation error.
  sim_detail::Patrol patrol;
  for (size_t f = 0; f < floors_.size(); ++f) {
    SimulationSettings floor_settings = settings_;
    floor_settings.seed = siteFloorSeed(settings_.seed, static_cast<int>(f));
    sim_detail::Patrol p = sim_detail::patrolSession(floors_[f], floor_settings, s);
    const Eigen::Vector3d up(0.0, 0.0, static_cast<double>(f) * kSiteFloorHeight_m);
    floors_json.push_back({{"floor", f},
                           {"first_frame", patrol.true_poses.size()},
                           {"frames", p.true_poses.size()},
                           {"localisation_offset",
                            {p.offset_x_m, p.offset_y_m, p.offset_yaw_rad * 180.0 / std::numbers::pi}}});
    if (f == 0) {
      patrol.offset_x_m = p.offset_x_m;
      patrol.offset_y_m = p.offset_y_m;
      patrol.offset_yaw_rad = p.offset_yaw_rad;
    }
    for (size_t i = 0; i < p.true_poses.size(); ++i) {
      p.true_poses[i].translation() += up;
      p.estimated[i].translation() += up;
      patrol.true_poses.push_back(p.true_poses[i]);
      patrol.estimated.push_back(p.estimated[i]);
    }
  }
  return patrol;
}

// The session's TUM folder: images, their lists, both trajectories and the intrinsics.
void Simulation::writeFrames(int s, const fs::path& dir, const sim_detail::Patrol& patrol) const {
  const size_t frames = patrol.true_poses.size();
  std::error_code ec;
  fs::create_directories(dir / "rgb", ec);
  fs::create_directories(dir / "depth", ec);
  if (ec) throw IoError(dir.string() + ": cannot create folder (" + ec.message() + ")");
  const Renderer renderer(state_);
  std::vector<std::string> stamps(frames);
  for (size_t i = 0; i < frames; ++i) {
    char st[32];
    std::snprintf(st, sizeof st, "%.6f", times_[static_cast<size_t>(s)] + 0.5 * static_cast<double>(i));
    stamps[i] = st;
  }
  parallelFor(frames, settings_.threads, [&](size_t i) {
    const RenderedFrame f = renderer.render(rig_.camera, patrol.true_poses[i], rig_.sensor,
                                            hours_[static_cast<size_t>(s)],
                                            mix(settings_.seed, (static_cast<uint64_t>(s) << 20) + i),
                                            use_daylight_ ? &daylight_ : nullptr);
    writePngStaged(dir / "rgb" / (stamps[i] + ".png"), f.rgb);
    writePngStaged(dir / "depth" / (stamps[i] + ".png"), f.depth);
  });
  std::string rgb_txt = "# color images\n# timestamp filename\n", depth_txt = "# depth maps\n# timestamp filename\n";
  std::string gt = "# true camera poses\n# timestamp tx ty tz qx qy qz qw\n";
  std::string traj = rig_.sensor.kind == SensorKind::Ideal
                         ? "# estimated camera poses (localisation with offset and drift)\n# timestamp tx ty tz qx qy qz qw\n"
                         : "# estimated camera poses (odometry from the localisation offset, drifting)\n"
                           "# timestamp tx ty tz qx qy qz qw\n";
  for (size_t i = 0; i < frames; ++i) {
    const double stamp = times_[static_cast<size_t>(s)] + 0.5 * static_cast<double>(i);
    rgb_txt += stamps[i] + " rgb/" + stamps[i] + ".png\n";
    depth_txt += stamps[i] + " depth/" + stamps[i] + ".png\n";
    gt += poseLine(stamp, patrol.true_poses[i]);
    traj += poseLine(stamp, patrol.estimated[i]);
  }
  writeText(dir / "rgb.txt", rgb_txt);
  writeText(dir / "depth.txt", depth_txt);
  writeText(dir / "groundtruth.txt", gt);
  writeText(dir / "trajectory.txt", traj);
  char k[128];
  std::snprintf(k, sizeof k, "%.6f %.6f %.6f %.6f\n", rig_.camera.fx, rig_.camera.fy, rig_.camera.cx, rig_.camera.cy);
  writeText(dir / "camera-intrinsics.txt", k);
}

// Ground truth of this session: its occupancy and its objects.
void Simulation::writeTruth(int s, const std::vector<VoxelKey>& truth) const {
  // Numbered with three digits where there can be more than 100 sessions, so that names sort.
  const char* const occupancy_format = site_ ? "occupancy_%03d.cmap" : "occupancy_%02d.cmap";
  const char* const objects_format = site_ ? "objects_%03d.json" : "objects_%02d.json";
  const SessionMap occupancy = sim_detail::truthMap(truth, rig_.grid);
  char truth_name[64];
  std::snprintf(truth_name, sizeof truth_name, occupancy_format, s);
  writeSessionMap(root_ / "truth" / truth_name,
                      occupancy, {{"created_by", "chronomap simulate"}, {"truth", true}, {"session", s}});
  std::snprintf(truth_name, sizeof truth_name, objects_format, s);
  writeText(root_ / "truth" / truth_name, objectsJson(state_).dump(1) + "\n");
}

void Simulation::session(int s) {
  const std::vector<ScheduledChange> changes = changesOf(s);
  if (s >= repaint_at_ && repaint_at_ >= 0) repaint(s);
  const std::vector<VoxelKey> truth = truthOccupancy(state_, rig_.grid);
  addEvents(s, changes, truth);
  nlohmann::json floors_json = nlohmann::json::array();
  const sim_detail::Patrol patrol = patrolOf(s, floors_json);
  const size_t frames = patrol.true_poses.size();

  char name[32];
  // Numbered with three digits where there can be more than 100 sessions, so that names sort.
  std::snprintf(name, sizeof name, site_ ? "session_%03d" : "session_%02d", s);
  writeFrames(s, root_ / name, patrol);
  writeTruth(s, truth);

  const double time_s = times_[static_cast<size_t>(s)];
  const double offset_yaw_deg = patrol.offset_yaw_rad * 180.0 / std::numbers::pi;
  sessions_json_.push_back({{"index", s},
                            {"dir", name},
                            {"time_s", time_s},
                            {"time", formatTime(time_s)},
                            {"hour", hours_[static_cast<size_t>(s)]},
                            {"frames", frames},
                            {"changes", changes.size()},
                            {"weekday", scheduleDay(settings_.seed, static_cast<int>(std::floor((time_s -
                                                                                   kScheduleStart_s) / 86400.0)))
                                           .weekday},
                            {"localisation_offset", {patrol.offset_x_m, patrol.offset_y_m, offset_yaw_deg}}});
  if (site_) sessions_json_.back()["floors"] = floors_json;
  summary_.session_dirs.push_back(out_ / name);
  summary_.times_s.push_back(time_s);
  summary_.hours.push_back(hours_[static_cast<size_t>(s)]);
  summary_.frames += frames;
  previous_truth_ = truth;
  previous_state_ = state_;
}

// The true schedule: every routine with its rule and objects, and each day's exceptions.
nlohmann::json Simulation::scheduleJson() const {
  nlohmann::json routines = nlohmann::json::array(), days = nlohmann::json::array();
  for (const Routine& r : routinesOf(home_)) {
    routines.push_back({{"name", r.name}, {"rule", r.rule}, {"objects", r.objects}});
  }
  const int last_day = static_cast<int>((times_.back() - kScheduleStart_s) / 86400.0);
  for (int d = 0; d <= last_day; ++d) {
    const ScheduleDay day_exceptions = scheduleDay(settings_.seed, d);
    days.push_back({{"day", d},
                    {"date", formatTime(kScheduleStart_s + 86400.0 * d).substr(0, 10)},
                    {"weekday", day_exceptions.weekday},
                    {"worker_away", day_exceptions.worker_away},
                    {"weekend_visit", day_exceptions.weekend_visit},
                    {"meeting_cancelled", day_exceptions.meeting_cancelled}});
  }
  nlohmann::json schedule = {{"start", formatTime(kScheduleStart_s)},
                             {"clock", "UTC"},
                             {"routines", routines},
                             {"days", days}};
  if (settings_.rare_events) schedule["rare_events"] = rare_json_;
  return schedule;
}

// The true illumination: the curves sampled every quarter hour, and the rule for the place.
nlohmann::json Simulation::lightingJson() const {
  nlohmann::json hours_json = nlohmann::json::array(), ceiling = nlohmann::json::array(),
                 sun = nlohmann::json::array();
  for (int q = 0; q <= 96; ++q) {
    const double h = 0.25 * q;
    const Eigen::Vector3d c = Daylight::ceiling(h), d = Daylight::daylight(h);
    hours_json.push_back(h);
    ceiling.push_back({c.x(), c.y(), c.z()});
    sun.push_back({d.x(), d.y(), d.z()});
  }
  return {{"model", "daylight"},
          {"rule", "colour = albedo * (ceiling(hour) + window(p) * daylight(hour)), per channel"},
          {"window", "exp(-d / 2 m), d = horizontal distance to the nearest outer wall"},
          {"building_min", {state_.bounds.min().x(), state_.bounds.min().y(), state_.bounds.min().z()}},
          {"building_max", {state_.bounds.max().x(), state_.bounds.max().y(), state_.bounds.max().z()}},
          {"hours", hours_json},
          {"ceiling", ceiling},
          {"daylight", sun}};
}

// A sensor model other than the ideal one, with every constant (docs/simulator.md).
nlohmann::json sensorJson(const SensorModel& sensor) {
  const DepthCameraModel& c = sensor.camera;
  const OdometryModel& o = sensor.odometry;
  return {{"model", toString(sensor.kind)},
          {"depth_scale", sensor.depth_scale},
          {"min_range_m", sensor.min_range_m},
          {"max_range_m", sensor.max_range_m},
          {"dark_luminance", sensor.dark_luminance},
          {"axial_sigma", "a + b (z - z0)^2 + c / sqrt(z) * theta^2 / (pi/2 - theta)^2 (Nguyen, Izadi, Lovell 2012)"},
          {"axial_a_m", c.axial_a_m},
          {"axial_b_per_m", c.axial_b_per_m},
          {"axial_z0_m", c.axial_z0_m},
          {"axial_incidence_m", c.axial_incidence_m},
          {"lateral_px", c.lateral_px},
          {"lateral_incidence_px", c.lateral_incidence_px},
          {"lateral_max_px", c.lateral_max_px},
          {"baseline_m", c.baseline_m},
          {"focal_px", c.focal_px},
          {"disparity_step_px", c.disparity_step_px},
          {"max_incidence_deg", c.max_incidence_deg},
          {"edge_dropout", c.edge_dropout},
          {"flying_pixel", c.flying_pixel},
          {"dark_dropout", c.dark_dropout},
          {"dark_bias_m", c.dark_bias_m},
          {"shiny_dropout", c.shiny_dropout},
          {"shiny_bias_m", c.shiny_bias_m},
          {"shiny", "the tops of desks and tables, robots, the cleaning cart's handle"},
          {"odometry",
           {{"translation_m_per_sqrt_m", o.translation_m_per_sqrt_m},
            {"yaw_deg_per_sqrt_m", o.yaw_deg_per_sqrt_m},
            {"yaw_deg_per_sqrt_rad", o.yaw_deg_per_sqrt_rad},
            {"scale_sigma", o.scale_sigma},
            {"yaw_bias_deg_per_m", o.yaw_bias_deg_per_m}}}};
}

void Simulation::writeScene() {
  const Camera& camera = rig_.camera;
  const SensorModel& sensor = rig_.sensor;
  nlohmann::json scene = {{"created_by", "chronomap simulate"},
                          {"preset", settings_.preset},
                          {"seed", settings_.seed},
                          {"voxel_resolution_m", settings_.voxel_resolution_m},
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
                          {"sessions", sessions_json_},
                          {"events", EventSpool::kMarker}};
  if (sensor.kind != SensorKind::Ideal) scene["sensor"] = sensorJson(sensor);
  if (rhythmic_) scene["schedule"] = scheduleJson();
  if (use_daylight_) scene["lighting"] = lightingJson();
  if (settings_.repaint) scene["repaints"] = repaints_json_;
  if (site_) {
    scene["site"] = {{"floors", settings_.floors},
                     {"floor_height_m", kSiteFloorHeight_m},
                     {"object_id_stride", kSiteIdStride},
                     {"building", "each floor a floor66 building of its own seed, floor f raised by f * floor_height_m"},
                     {"patrols", "one a night from 22:00 to 03:00 (UTC), the floors one after the other"}};
  }
  for (const Room& r : state_.rooms) {
    scene["rooms"].push_back({{"name", r.name},
                              {"min", {r.area.min().x(), r.area.min().y()}},
                              {"max", {r.area.max().x(), r.area.max().y()}}});
  }
  events_.writeScene(root_ / "scene.json", scene.dump(1) + "\n");
}

}  // namespace

SimulationSummary simulate(const SimulationSettings& settings, const fs::path& out,
                           const SimulationProgress& progress) {
  const auto started = std::chrono::steady_clock::now();
  const PresetPlan plan = presetPlan(settings.preset);
  SceneState state = makeScene(settings.preset, settings.seed);  // validates the preset
  const int sessions = settings.sessions > 0 ? settings.sessions : plan.sessions;
  checkSettings(settings, sessions);
  const KeyGrid grid(settings.voxel_resolution_m);
  const Camera camera = kinectCamera(settings.resolution_scale);
  SensorModel sensor = sensorModel(parseSensorKind(settings.sensor));
  sensor.noise_per_m2 = settings.noise_per_m2;
  // Written whole or not at all: into a staging folder beside `out`, moved into place at the end.
  StagedFolder staged(out);
  const fs::path& root = staged.path();
  std::error_code ec;
  fs::create_directories(root / "truth", ec);
  if (ec) throw IoError(out.string() + ": cannot create folder (" + ec.message() + ")");
  std::unique_ptr<tbb::global_control> limit;
  if (settings.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<size_t>(settings.threads));
  }
  const SessionTimes times = sessionTimes(settings, plan, sessions);
  const Rig rig{grid, camera, sensor};
  Simulation simulation(settings, rig, out, root, times, std::move(state), sessions);
  for (int s = 0; s < sessions; ++s) {
    simulation.session(s);
    if (progress) progress(static_cast<size_t>(s) + 1, static_cast<size_t>(sessions));
  }
  simulation.writeScene();
  staged.commit();
  SimulationSummary summary = std::move(simulation.summary());
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return summary;
}

}  // namespace chronomap
