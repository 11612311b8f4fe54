// The workflows on 4D map files (build, chronomap::addSession) and what the bindings
// share for them: times as epoch seconds, ISO-8601 strings or datetimes, checked as the command line checks them.
// (Progress forwarded to Python, and Ctrl-C: LongCall in guards.cpp.)

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "bindings.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"
#include "chronomap/pipeline/map4d.h"

namespace chronomap::python {

UpSettings toUpSettings(const py::object& up) {
  if (up.is_none()) return {};
  if (py::isinstance<py::str>(up)) {
    const std::string name = up.cast<std::string>();
    if (name == "auto") return {std::nullopt, true};
    try {
      return {parseUpAxis(name), false};
    } catch (const UsageError&) {
      // refused below, naming the argument
    }
  }
  throw UsageError("up must be '+x', '-x', '+y', '-y', '+z', '-z', 'auto' or None, not " +
                   py::repr(up).cast<std::string>());
}

double toSeconds(const py::handle& time, const char* name) {
  const py::module_ datetime = py::module_::import("datetime");
  if (py::isinstance(time, datetime.attr("datetime"))) {
    py::object t = py::reinterpret_borrow<py::object>(time);
    if (t.attr("tzinfo").is_none()) t = t.attr("replace")(py::arg("tzinfo") = datetime.attr("timezone").attr("utc"));
    const double seconds = t.attr("timestamp")().cast<double>();
    return checkTime(seconds, std::string(name) + " " + exactNumber(seconds));
  }
  if (py::isinstance<py::str>(time)) {
    // The command line's own parser and checks: ISO-8601 ("2012-03-01T10:00:00Z", a zone or
    // none, a date alone) or seconds as text, the same times --time and MAP@T take.
    try {
      return parseTime(time.cast<std::string>());
    } catch (const UsageError& e) {
      // parseTime names the value as "time '...'": name the argument instead ("t1 '...'").
      const std::string what = e.what();
      throw UsageError(std::string(name) + (what.rfind("time ", 0) == 0 ? what.substr(4) : ": " + what));
    }
  }
  if (py::isinstance<py::bool_>(time) || !(py::isinstance<py::float_>(time) || py::isinstance<py::int_>(time) ||
                                            py::hasattr(time, "__float__"))) {
    std::string msg(name);
    msg.append(": expected epoch seconds, an ISO-8601 string or a datetime.datetime, got ");
    throw py::type_error(msg.append(py::str(py::type::handle_of(time).attr("__name__")).cast<std::string>()));
  }
  const double seconds = time.cast<double>();
  return checkTime(seconds, std::string(name) + " " + exactNumber(seconds));
}

py::object toDatetime(double time_s) {
  const py::module_ datetime = py::module_::import("datetime");
  return datetime.attr("datetime").attr("fromtimestamp")(time_s, datetime.attr("timezone").attr("utc"));
}

namespace {

/// Rigid motions as an (N, 4, 4) float64 array of their matrices.
py::object posesArray(const std::vector<Eigen::Isometry3d>& poses) {
  std::vector<double> values;
  values.reserve(poses.size() * 16);
  for (const Eigen::Isometry3d& T : poses) {
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) values.push_back(T.matrix()(r, c));
    }
  }
  return vectorArray(std::move(values)).attr("reshape")(static_cast<py::ssize_t>(poses.size()), 4, 4);
}

py::dict correctionDict(const PoseCorrection& c) {
  py::dict d;
  d["model"] = toString(c.model);
  d["motion"] = posesArray({c.motion}).attr("__getitem__")(0);
  d["per_frame"] = c.per_frame.empty() ? py::object(py::none()) : py::object(posesArray(c.per_frame));
  return d;
}

py::dict builtSessionDict(const BuiltSession& b) {
  py::dict d;
  d["dataset"] = b.dataset;
  d["time_s"] = b.time_s;
  d["points"] = b.points;
  d["nodes_added"] = b.nodes_added;
  d["nodes_separate"] = b.nodes_separate;
  d["entries_added"] = b.report.entries_added;
  d["entries_removed"] = b.report.entries_removed;
  if (b.correction) {
    const Eigen::Isometry3d& c = b.correction->motion;
    d["registration_m"] = vector3Array(c.translation());
    d["correction"] = correctionDict(*b.correction);
  }
  d["recorded_poses"] = posesArray(b.recorded_poses);
  d["poses"] = posesArray(b.poses);
  if (b.realigned_voxels) d["realigned_voxels"] = *b.realigned_voxels;
  return d;
}

py::dict buildPy(const std::filesystem::path& map, const std::vector<std::filesystem::path>& datasets,
                 const py::object& times, double resolution_m, bool fast, double max_range_m, int threads,
                 const std::string& format, const py::object& register_sessions, std::optional<int> registration_rounds, bool realign,
                 bool replace, const py::object& progress, bool carve_beyond_range, const py::object& up,
                 double depth_edges) {
  BuildSettings settings;
  settings.map = map;
  settings.datasets = datasets;
  if (!times.is_none()) {
    for (const py::handle t : times) {
      settings.times_s.push_back(t.is_none() ? std::nullopt : std::optional<double>(toSeconds(t, "times")));
    }
  }
  settings.session.resolution_m = resolution_m;
  settings.session.integrator.fast = fast;
  settings.session.integrator.max_range_m = max_range_m;
  settings.session.integrator.carve_beyond_range = carve_beyond_range;
  settings.session.integrator.depth_edge_ratio = depth_edges;
  settings.session.integrator.threads = threads;
  settings.session.dataset.format = parseRecordingFormat(format);
  settings.session.up = toUpSettings(up);
  // register: a preset's name ("localiser", "odometry"), or anything else by its truth (plain).
  std::optional<RegistrationSettings> registration;
  if (py::isinstance<py::str>(register_sessions)) {
    registration = registrationNamed(register_sessions.cast<std::string>());
  } else if (PyObject_IsTrue(register_sessions.ptr()) == 1) {
    registration = RegistrationSettings{};
  } else if (PyErr_Occurred()) {
    throw py::error_already_set();
  }
  if (registration && registration_rounds) registration->rounds = *registration_rounds;  // else the preset's (3)
  settings.registration = registration;
  if (realign) settings.realign = RealignSettings{};
  settings.replace = replace;
  LongCall call(progress);
  settings.progress = call.progress();
  const BuildResult result = call.run([&] { return build(settings); });
  py::dict d;
  d["created"] = result.created;
  d["sessions"] = result.sessions;
  d["nodes"] = result.nodes;
  d["file_bytes"] = result.file_bytes;
  d["up"] = toString(result.up.axis);
  d["up_from"] = result.up.from;
  py::list added;
  for (const auto& b : result.added) added.append(builtSessionDict(b));
  d["added"] = added;
  return d;
}

py::dict addSessionPy(const std::filesystem::path& map, const std::filesystem::path& session, const py::object& time,
                      bool replace, const std::string& write, bool realign) {
  AddSessionSettings settings;
  settings.map = map;
  settings.session = session;
  if (!time.is_none()) settings.time_s = toSeconds(time, "time");
  settings.replace = replace;
  settings.write = parseWritePolicy(write);
  if (realign) settings.realign = RealignSettings{};
  AddSessionResult r;
  {
    py::gil_scoped_release release;
    r = chronomap::addSession(settings);
  }
  py::dict d;
  d["created"] = r.created;
  d["appended"] = r.appended;
  d["time_s"] = r.time_s;
  d["entries_added"] = r.report.entries_added;
  d["entries_removed"] = r.report.entries_removed;
  d["nodes_added"] = r.nodes_added;
  d["record_bytes"] = r.record_bytes;
  if (r.realigned_voxels) d["realigned_voxels"] = *r.realigned_voxels;
  d["sessions"] = r.sessions;
  d["nodes"] = r.nodes;
  d["file_bytes"] = r.file_bytes;
  return d;
}

}  // namespace

void bindPipeline(py::module_& m) {
  m.def("build", &buildPy, py::arg("map"), py::arg("datasets"), py::arg("times") = py::none(),
        py::arg("resolution_m") = 0.05, py::arg("fast") = false, py::arg("max_range_m") = 3.0, py::arg("threads") = 0,
        py::arg("format") = "auto", py::arg("register") = false, py::arg("registration_rounds") = py::none(),
        py::arg("realign") = false, py::arg("replace") = false, py::arg("progress") = py::none(),
        py::arg("carve_beyond_range") = false, py::arg("up") = py::none(), py::arg("depth_edges") = 0.0,
        "Builds or extends the 4D map file `map` from recordings, one session each, as `chronomap build` "
        "does: integrated, ordered by time, registered to their consensus (register=True; or a preset's name, "
        "'localiser' or 'odometry', as `--register-preset`) and re-aligned "
        "(realign=True) when asked, added and written once, atomically. `up`: which axis of the recordings' "
        "world frame is up ('+x' .. '-z', 'auto': estimated from the floor on the first recording; None: +z, or "
        "the map's own), every recording turned so that it becomes +z (`--up`, docs/frames.md); the summary's "
        "`up` and `up_from` say which. `times`: one per dataset (epoch "
        "seconds, ISO-8601 string, datetime, or None for the dataset's own first timestamp), or None. `progress(label, done, "
        "total)` is called as work advances; Ctrl-C stops the work at the next frame, writing nothing. Returns a "
        "summary dict with one entry per added session (in time order): `poses` and `recorded_poses` ((F, 4, 4) "
        "T_world_sensor of each frame, as integrated and as the recording gives them) and, with registration, "
        "`correction` (`model`, `motion` (4, 4), `per_frame` (F, 4, 4) or None) and `registration_m`.");
  m.def("add_session", &addSessionPy, py::arg("map"), py::arg("session"), py::arg("time") = py::none(),
        py::arg("replace") = false, py::arg("write") = "auto", py::arg("realign") = false,
        "Adds the session map file `session` to the 4D map file `map` (created when missing), as `chronomap "
        "add` does: appended or rewritten (`write`: 'auto', 'append', 'rewrite'), under the map's file "
        "lock. `time`: epoch seconds, ISO-8601 string or datetime; default the time the session file records.");
}

}  // namespace chronomap::python
