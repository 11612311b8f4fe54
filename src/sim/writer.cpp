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

namespace chronomap::sim {

namespace fs = std::filesystem;

namespace {

using detail::centerOf;
using detail::kCameraHeight;
using detail::kCameraPitchDeg;
using detail::mix;
using detail::Rng;

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
  if (settings.preset == "site" && (settings.floors < 1 || settings.floors > 50)) {
    throw UsageError("--floors must lie between 1 and 50");
  }
  if (settings.lighting != "fixed" && settings.lighting != "daylight") {
    throw UsageError("--lighting must be fixed or daylight, not '" + settings.lighting + "'");
  }
  const KeyGrid grid(settings.voxel_resolution_m);
  const Camera camera = kinectCamera(settings.resolution_scale);
  SensorModel sensor;
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

  // Session times: 2 or 3 sessions on a recording day, at different hours, a day or two apart;
  // for the rhythmic building ("weeks"), two a day every day from its first Monday, one in the
  // morning half of the day and one in the evening half, at any hour, nights included.
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

  SimulationSummary summary;
  nlohmann::json sessions_json = nlohmann::json::array();
  // The change events go to a file in the staging folder as they come, already formatted as
  // elements of scene.json's "events" (their voxels make them most of scene.json: about 4 MB a
  // night on the site, far more than memory should hold for a year); writeScene() splices them.
  EventSpool events(root / ".events.tmp");
  std::vector<VoxelKey> previous_truth;
  SceneState previous_state;
  if (settings.rare_events) {
    if (!rhythmic) throw UsageError("--rare-events needs the weeks preset");
    addRareObjects(state, settings.seed);
  }
  const SceneState home = state;
  // The site's floors, each in its own frame with its own change processes and patrol.
  std::vector<SceneState> floors;
  for (int f = 0; site && f < settings.floors; ++f) floors.push_back(siteFloor(settings.seed, f));
  // Numbered with three digits where there can be more than 100 sessions, so that names sort.
  const char* const session_format = site ? "session_%03d" : "session_%02d";
  const char* const occupancy_format = site ? "occupancy_%03d.cmap" : "occupancy_%02d.cmap";
  const char* const objects_format = site ? "objects_%03d.json" : "objects_%02d.json";
  Daylight daylight;
  daylight.building = state.bounds;
  const bool use_daylight = settings.lighting == "daylight";
  // The repainted object: the first table no routine moves (else the first such desk), repainted
  // from session repaint_at on.
  const int repaint_at = settings.repaint ? std::max(1, sessions - sessions / 4) : -1;
  uint32_t repaint_object = 0;
  if (settings.repaint) {
    std::vector<uint32_t> routine_objects;
    for (const Routine& r : routinesOf(home)) routine_objects.insert(routine_objects.end(), r.objects.begin(), r.objects.end());
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
  }
  const Rgb repaint_colour{196, 52, 44};  // a red unlike any face colour of the presets
  nlohmann::json repaints_json = nlohmann::json::array();
  std::vector<uint32_t> rare_before;  // the objects the previous session's rare event changed
  nlohmann::json rare_json = nlohmann::json::array();
  for (int s = 0; s < sessions; ++s) {
    // Each change with its cause: a routine of the schedule, or the random processes.
    std::vector<ScheduledChange> changes;
    if (rhythmic) {
      const SceneState before = state;
      changes = applySchedule(state, home, settings.seed, times[static_cast<size_t>(s)]);
      if (settings.rare_events) {
        // The schedule, then the session's rare event on top; each change labelled with its cause.
        std::map<uint32_t, std::string> routine_of;
        for (const Routine& r : routinesOf(home)) {
          for (uint32_t id : r.objects) routine_of[id] = r.name;
        }
        std::vector<uint32_t> rare_now;
        const auto rare = rareEventOf(settings.seed, s, times);
        if (rare) {
          rare_now = applyRareEvent(state, home, settings.seed, s, *rare);
          rare_json.push_back({{"session", s}, {"what", describe(*rare)}, {"objects", rare_now}});
        }
        changes = objectChanges(before, state);
        for (ScheduledChange& c : changes) {
          const auto in = [&](const std::vector<uint32_t>& ids) {
            return std::find(ids.begin(), ids.end(), c.object) != ids.end();
          };
          const auto r = routine_of.find(c.object);
          c.routine = r == routine_of.end() ? std::string() : r->second;
          if (in(rare_now)) {
            c.cause = "rare";
            c.routine = describe(*rare);
          } else if (in(rare_before)) {
            c.cause = "after_rare";
          }
        }
        rare_before = rare_now;
      }
      if (s == 0) changes.clear();  // the first session's state is where the history starts
    } else if (site) {
      for (size_t f = 0; f < floors.size() && s > 0; ++f) {
        for (const auto& [id, kind] : applyChanges(floors[f], siteFloorSeed(settings.seed, static_cast<int>(f)), s)) {
          changes.push_back({static_cast<uint32_t>(f) * kSiteIdStride + id, kind, {}});
        }
      }
      state = stackFloors(floors);
    } else if (s > 0) {
      for (const auto& [id, kind] : applyChanges(state, settings.seed, s)) changes.push_back({id, kind, {}});
    }
    if (s >= repaint_at && repaint_at >= 0) {
      // Applied after the session's changes, so that a schedule restoring objects from home
      // cannot undo it.
      for (Object& o : state.objects) {
        if (o.id != repaint_object) continue;
        if (s == repaint_at) {
          nlohmann::json voxels = nlohmann::json::array();
          for (const VoxelKey& k : objectVoxels(o, grid)) voxels.push_back({k.x, k.y, k.z});
          const Rgb was = o.parts.front().face_colors[5];
          repaints_json.push_back({{"from_session", s - 1},
                                   {"to_session", s},
                                   {"object", o.id},
                                   {"object_kind", toString(o.kind)},
                                   {"from", {was.r, was.g, was.b}},
                                   {"to", {repaint_colour.r, repaint_colour.g, repaint_colour.b}},
                                   {"voxel_count", voxels.size()},
                                   {"voxels", voxels}});
        }
        for (Part& part : o.parts) part.face_colors.fill(repaint_colour);
      }
    }
    const std::vector<VoxelKey> truth = truthOccupancy(state, grid);
    // Change events with the truth voxels each one changes.
    for (const auto& [id, kind, routine, cause] : changes) {
      ChangeEvent e = detail::changeEvent(id, kind, previous_state, state, previous_truth, truth, grid);
      e.from_session = static_cast<uint32_t>(s - 1);
      if (e.voxels.empty()) continue;  // hidden by other objects: nothing a map could see
      nlohmann::json voxels = nlohmann::json::array();
      for (const VoxelKey& k : e.voxels) voxels.push_back({k.x, k.y, k.z});
      events.add({{"from_session", e.from_session},
                             {"to_session", s},
                             {"object", e.object},
                             {"object_kind", toString(e.object_kind)},
                             {"kind", toString(e.kind)},
                             {"cause", rhythmic ? cause : "random"},
                             {"routine", routine},
                             {"voxel_count", e.voxels.size()},
                             {"voxels", voxels}});
      ++summary.events;
    }

    // The patrol, true and estimated poses.
    detail::Patrol patrol;
    nlohmann::json floors_json = nlohmann::json::array();
    if (site) {
      // One patrol per floor, one after the other, each with its own localisation error.
      for (size_t f = 0; f < floors.size(); ++f) {
        SimulationSettings floor_settings = settings;
        floor_settings.seed = siteFloorSeed(settings.seed, static_cast<int>(f));
        detail::Patrol p = detail::patrolSession(floors[f], floor_settings, s);
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
    } else {
      patrol = detail::patrolSession(state, settings, s);
    }
    const size_t frames = patrol.true_poses.size();

    char name[32];
    std::snprintf(name, sizeof name, session_format, s);
    const fs::path dir = root / name;
    fs::create_directories(dir / "rgb", ec);
    fs::create_directories(dir / "depth", ec);
    if (ec) throw IoError(dir.string() + ": cannot create folder (" + ec.message() + ")");
    const Renderer renderer(state);
    std::vector<std::string> stamps(frames);
    for (size_t i = 0; i < frames; ++i) {
      char st[32];
      std::snprintf(st, sizeof st, "%.6f", times[static_cast<size_t>(s)] + 0.5 * static_cast<double>(i));
      stamps[i] = st;
    }
    parallelFor(frames, settings.threads, [&](size_t i) {
      const RenderedFrame f = renderer.render(camera, patrol.true_poses[i], sensor, hours[static_cast<size_t>(s)],
                                              mix(settings.seed, (static_cast<uint64_t>(s) << 20) + i),
                                              use_daylight ? &daylight : nullptr);
      writePngStaged(dir / "rgb" / (stamps[i] + ".png"), f.rgb);
      writePngStaged(dir / "depth" / (stamps[i] + ".png"), f.depth);
    });
    std::string rgb_txt = "# color images\n# timestamp filename\n", depth_txt = "# depth maps\n# timestamp filename\n";
    std::string gt = "# true camera poses\n# timestamp tx ty tz qx qy qz qw\n";
    std::string traj = "# estimated camera poses (localisation with offset and drift)\n# timestamp tx ty tz qx qy qz qw\n";
    for (size_t i = 0; i < frames; ++i) {
      const double stamp = times[static_cast<size_t>(s)] + 0.5 * static_cast<double>(i);
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
    std::snprintf(k, sizeof k, "%.6f %.6f %.6f %.6f\n", camera.fx, camera.fy, camera.cx, camera.cy);
    writeText(dir / "camera-intrinsics.txt", k);

    // Ground truth of this session.
    const SessionMap occupancy = detail::truthMap(truth, grid);
    char truth_name[64];
    std::snprintf(truth_name, sizeof truth_name, occupancy_format, s);
    writeSessionMap(root / "truth" / truth_name,
                        occupancy, {{"created_by", "chronomap simulate"}, {"truth", true}, {"session", s}});
    std::snprintf(truth_name, sizeof truth_name, objects_format, s);
    writeText(root / "truth" / truth_name, objectsJson(state).dump(1) + "\n");

    const double offset_yaw_deg = patrol.offset_yaw_rad * 180.0 / std::numbers::pi;
    sessions_json.push_back({{"index", s},
                             {"dir", name},
                             {"time_s", times[static_cast<size_t>(s)]},
                             {"time", formatTime(times[static_cast<size_t>(s)])},
                             {"hour", hours[static_cast<size_t>(s)]},
                             {"frames", frames},
                             {"changes", changes.size()},
                             {"weekday", scheduleDay(settings.seed, static_cast<int>(std::floor((times[static_cast<size_t>(s)] -
                                                                                   kScheduleStart_s) / 86400.0)))
                                            .weekday},
                             {"localisation_offset", {patrol.offset_x_m, patrol.offset_y_m, offset_yaw_deg}}});
    if (site) sessions_json.back()["floors"] = floors_json;
    summary.session_dirs.push_back(out / name);
    summary.times_s.push_back(times[static_cast<size_t>(s)]);
    summary.hours.push_back(hours[static_cast<size_t>(s)]);
    summary.frames += frames;
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
                          {"events", EventSpool::kMarker}};
  if (rhythmic) {
    // The true schedule: every routine with its rule and objects, and each day's exceptions.
    nlohmann::json routines = nlohmann::json::array(), days = nlohmann::json::array();
    for (const Routine& r : routinesOf(home)) {
      routines.push_back({{"name", r.name}, {"rule", r.rule}, {"objects", r.objects}});
    }
    const int last_day = static_cast<int>((times.back() - kScheduleStart_s) / 86400.0);
    for (int d = 0; d <= last_day; ++d) {
      const ScheduleDay day_exceptions = scheduleDay(settings.seed, d);
      days.push_back({{"day", d},
                      {"date", formatTime(kScheduleStart_s + 86400.0 * d).substr(0, 10)},
                      {"weekday", day_exceptions.weekday},
                      {"worker_away", day_exceptions.worker_away},
                      {"weekend_visit", day_exceptions.weekend_visit},
                      {"meeting_cancelled", day_exceptions.meeting_cancelled}});
    }
    scene["schedule"] = {{"start", formatTime(kScheduleStart_s)},
                         {"clock", "UTC"},
                         {"routines", routines},
                         {"days", days}};
    if (settings.rare_events) scene["schedule"]["rare_events"] = rare_json;
  }
  if (use_daylight) {
    // The true illumination: the curves sampled every quarter hour, and the rule for the place.
    nlohmann::json hours_json = nlohmann::json::array(), ceiling = nlohmann::json::array(),
                   sun = nlohmann::json::array();
    for (int q = 0; q <= 96; ++q) {
      const double h = 0.25 * q;
      const Eigen::Vector3d c = Daylight::ceiling(h), d = Daylight::daylight(h);
      hours_json.push_back(h);
      ceiling.push_back({c.x(), c.y(), c.z()});
      sun.push_back({d.x(), d.y(), d.z()});
    }
    scene["lighting"] = {{"model", "daylight"},
                         {"rule", "colour = albedo * (ceiling(hour) + window(p) * daylight(hour)), per channel"},
                         {"window", "exp(-d / 2 m), d = horizontal distance to the nearest outer wall"},
                         {"building_min", {state.bounds.min().x(), state.bounds.min().y(), state.bounds.min().z()}},
                         {"building_max", {state.bounds.max().x(), state.bounds.max().y(), state.bounds.max().z()}},
                         {"hours", hours_json},
                         {"ceiling", ceiling},
                         {"daylight", sun}};
  }
  if (settings.repaint) scene["repaints"] = repaints_json;
  if (site) {
    scene["site"] = {{"floors", settings.floors},
                     {"floor_height_m", kSiteFloorHeight_m},
                     {"object_id_stride", kSiteIdStride},
                     {"building", "each floor a floor66 building of its own seed, floor f raised by f * floor_height_m"},
                     {"patrols", "one a night from 22:00 to 03:00 (UTC), the floors one after the other"}};
  }
  for (const Room& r : state.rooms) {
    scene["rooms"].push_back({{"name", r.name},
                              {"min", {r.area.min().x(), r.area.min().y()}},
                              {"max", {r.area.max().x(), r.area.max().y()}}});
  }
  events.writeScene(root / "scene.json", scene.dump(1) + "\n");
  staged.commit();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return summary;
}

}  // namespace chronomap::sim
