// TemporalMap: the 4D map from Python.

#include <filesystem>
#include <limits>
#include <utility>
#include <string>

#include <nlohmann/json.hpp>

#include "bindings.h"
#include "chronomap/analysis/change_frequency.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap::python {

namespace {

py::list historyOf(const TemporalMap& map, const py::handle& point) {
  const Eigen::Vector3d p = toVector3(point, "point");
  const ObjectLock lock(&map);
  py::list out;
  const auto key = map.grid().keyOf(p);
  if (!key) return out;
  // The entries of `chronomap history --json`, with the same names (time a datetime here).
  for (const HistoryEntry& e : map.history(*key)) {
    const Rgb rgb = e.counters.meanColour();
    py::dict d;
    d["time"] = toDatetime(e.time_s);
    d["time_s"] = e.time_s;
    d["state"] = toString(e.counters.state());
    d["probability"] = e.counters.probability();
    d["hits"] = e.counters.hits;
    d["length_m"] = e.counters.length_m;
    d["color"] = py::make_tuple(rgb.r, rgb.g, rgb.b);
    d["level"] = e.level;
    out.append(std::move(d));
  }
  return out;
}

py::dict addSession(TemporalMap& map, const SessionMap& session, const py::handle& time, const std::string& name,
                    bool replace) {
  const double time_s = toSeconds(time, "time");
  AddSettings options;
  options.name = name;
  options.replace = replace;
  AddReport report;
  {
    const ObjectLock lock(&map);
    py::gil_scoped_release release;
    report = map.add(time_s, session, options);
  }
  py::dict d;
  d["entries_added"] = report.entries_added;
  d["entries_removed"] = report.entries_removed;
  d["replaced"] = report.replaced;
  d["out_of_order"] = report.out_of_order;
  return d;
}

DiffMap diffTimes(const TemporalMap& map, const py::handle& t1, const py::handle& t2, const std::string& mode, double alpha,
                  int neighbourhood_voxels, double min_shift_voxels, int kept_surface_radius_voxels,
                  double kept_surface_share, int dark_surface_radius_voxels, double dark_surface_brightness,
                  double dark_surface_contrast, double dark_surface_share, double shift_plane_ratio) {
  const DiffSettings settings =
      diffSettings(mode, alpha, neighbourhood_voxels, min_shift_voxels, kept_surface_radius_voxels, kept_surface_share,
                   dark_surface_radius_voxels, dark_surface_brightness, dark_surface_contrast, dark_surface_share,
                   shift_plane_ratio);
  const double t1_s = toSeconds(t1, "t1"), t2_s = toSeconds(t2, "t2");
  const ObjectLock lock(&map);
  py::gil_scoped_release release;
  return diff(map, t1_s, t2_s, settings);
}

/// The interval (from, to] of the change layers; None means the whole history.
std::pair<double, double> interval(const py::object& from, const py::object& to) {
  const double inf = std::numeric_limits<double>::infinity();
  return {from.is_none() ? -inf : toSeconds(from, "from_time"), to.is_none() ? inf : toSeconds(to, "to_time")};
}

py::tuple changeCounts(const TemporalMap& map, const py::object& from, const py::object& to, uint32_t min_changes) {
  const auto [from_s, to_s] = interval(from, to);
  const ObjectLock lock(&map);
  ChangeFrequency f;
  {
    py::gil_scoped_release release;
    f = changeFrequency(map, from_s, to_s, min_changes);
  }
  std::vector<Eigen::Vector3d> centers(f.voxels.size());
  std::vector<uint32_t> counts(f.voxels.size());
  for (size_t i = 0; i < f.voxels.size(); ++i) {
    centers[i] = map.grid().centerOf(f.voxels[i].key);
    counts[i] = f.voxels[i].count;
  }
  return py::make_tuple(pointsArray(std::move(centers)), vectorArray(std::move(counts)));
}

py::array_t<uint64_t> changeHistogramPy(const TemporalMap& map, const py::object& from, const py::object& to) {
  const auto [from_s, to_s] = interval(from, to);
  const ObjectLock lock(&map);
  std::vector<uint64_t> h;
  {
    py::gil_scoped_release release;
    h = changeHistogram(map, from_s, to_s);
  }
  return vectorArray(std::move(h));
}

}  // namespace

void bindTemporal(py::module_& m) {
  // Every method that reads or changes the map holds its ObjectLock: threads sharing one map
  // run their calls one after another (even const calls: the change layers fill a cache).
  py::class_<TemporalMap>(m, "TemporalMap", "The 4D map: every observed state of a place, session by session.")
      .def(py::init([](double resolution_m, double colour_distance, double surface_shift_voxels,
                       double min_free_length_m, uint32_t min_hits) {
             ChangeCriterion c{0.0, colour_distance, surface_shift_voxels};
             c.min_free_length_m = min_free_length_m;
             c.min_hits = min_hits;
             return TemporalMap(resolution_m, c);
           }),
           py::arg("resolution_m") = 0.05, py::arg("color_distance") = 0.0,
           py::arg("surface_shift_voxels") = ChangeCriterion::kRecommendedSurfaceShift,
           py::arg("min_free_length_m") = 0.0, py::arg("min_hits") = 0,
           "An empty 4D map. color_distance > 0 also stores a change when a voxel's mean colour moves farther than "
           "that (8-bit RGB units), as `chronomap build --color-distance` does; ColourModel learns from those. "
           "surface_shift_voxels > 0 also stores one when the hits in an occupied voxel moved farther than that "
           "(voxels), as `chronomap build --surface-shift` does; the change search's shift test reads them. "
           "min_free_length_m and min_hits are the evidence rule of `chronomap build --min-free-length` and "
           "`--min-hits`: a grazing ray does not end an occupied state, a stray hit does not end a free one.")
      .def_static(
          "open",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return readTemporalMap(path);
          },
          py::arg("path"), "Reads a 4D map file (.cmap). Raises IoError or FormatError naming the file.")
      .def(
          "save",
          [](const TemporalMap& map, const std::filesystem::path& path) {
            const ObjectLock lock(&map);
            py::gil_scoped_release release;
            writeTemporalMap(path, map, nlohmann::json::object());
          },
          py::arg("path"), "Writes the 4D map file (.cmap), atomically.")
      .def_property_readonly("resolution_m", &TemporalMap::resolution_m,
                             "Voxel edge length in metres (fixed when the map is made: no lock).")
      .def_property_readonly(
          "times_s",
          [](const TemporalMap& map) {
            const ObjectLock lock(&map);
            return vectorArray(map.times());
          },
          "Session times (seconds since the epoch), increasing, as a float64 array.")
      .def_property_readonly(
          "times",
          [](const TemporalMap& map) {
            std::vector<double> times;
            {
              const ObjectLock lock(&map);
              times = map.times();
            }
            py::list out;
            for (double t : times) out.append(toDatetime(t));
            return out;
          },
          "Session times as aware datetime.datetime objects in UTC, increasing.")
      .def("add", &addSession, py::arg("session"), py::arg("time"), py::arg("name") = "", py::arg("replace") = false,
           "Adds a SessionMap observed at `time` (epoch seconds, an ISO-8601 string, or a datetime; naive ones are UTC); returns "
           "what changed in the map. Raises UsageError for a time already stored unless replace=True, or one outside "
           "the years 1 to 9999. Threads sharing the map run their calls on it one after another.")
      .def(
          "snapshot",
          [](const TemporalMap& map, const py::handle& time) {
            const double time_s = toSeconds(time, "time");
            const ObjectLock lock(&map);
            py::gil_scoped_release release;
            return map.snapshot(time_s);
          },
          py::arg("time"),
          "The SessionMap as most recently observed at `time` (epoch seconds, ISO-8601 string or datetime; empty before the first "
          "session).")
      .def("history", &historyOf, py::arg("point"),
           "The history of the voxel containing `point` (3,), as `chronomap history --json` lists it: one dict "
           "per stored change with `time` (UTC datetime), `time_s`, `state` ('unknown', 'free', 'occupied'), "
           "`probability`, `hits`, `length_m`, `color` (r, g, b; mean of the hits) and `level` (0: the voxel, "
           "k: a uniform cube of 2^k voxels a side); empty when never observed.")
      .def("change_counts", &changeCounts, py::arg("from_time") = py::none(), py::arg("to_time") = py::none(),
           py::arg("min_changes") = 1,
           "How often each part changed (the thesis' Figure 6b): (centers (N, 3) float64, counts (N,) uint32) of "
           "the unit voxels whose stored state changed at least min_changes times in (from_time, to_time] "
           "(None: the whole history).")
      .def("change_histogram", &changeHistogramPy, py::arg("from_time") = py::none(), py::arg("to_time") = py::none(),
           "histogram[n]: how many unit voxels changed exactly n times in (from_time, to_time], as uint64.")
      .def("diff", &diffTimes, py::arg("t1"), py::arg("t2"), py::arg("mode") = "hard", py::arg("alpha") = -1.0,
           py::arg("neighbourhood_voxels") = 0, py::arg("min_shift_voxels") = 0.0,
           py::arg("kept_surface_radius_voxels") = 0,
           py::arg("kept_surface_share") = DiffSettings::kDefaultKeptSurfaceShare,
           py::arg("dark_surface_radius_voxels") = 0,
           py::arg("dark_surface_brightness") = DiffSettings::kDefaultDarkSurfaceBrightness,
           py::arg("dark_surface_contrast") = DiffSettings::kDefaultDarkSurfaceContrast,
           py::arg("dark_surface_share") = DiffSettings::kDefaultDarkSurfaceShare, py::arg("shift_plane_ratio") = 0.0,
           "What changed from the state at t1 to the state at t2 (epoch seconds, ISO-8601 strings or datetimes): the diff of the two snapshots, visiting "
           "only what changed in between. Settings as chronomap.diff.")
      .def("__len__",
           [](const TemporalMap& map) {
             const ObjectLock lock(&map);
             return map.sessionCount();
           })
      .def("__eq__", [](const TemporalMap& a, const TemporalMap& b) {
        const ObjectLock lock(&a, &b);
        py::gil_scoped_release release;
        return a == b;
      });
}

}  // namespace chronomap::python
