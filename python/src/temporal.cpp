// TemporalMap: the 4D map from Python.

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "bindings.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap::python {

namespace {

py::list historyOf(const TemporalMap& map, const py::handle& point) {
  const Eigen::Vector3d p = toVector3(point, "point");
  py::list out;
  const auto key = map.grid().keyOf(p);
  if (!key) return out;
  for (const HistoryEntry& e : map.history(*key)) {
    out.append(py::make_tuple(e.time_s, static_cast<int>(e.counters.state())));
  }
  return out;
}

py::dict addSession(TemporalMap& map, const SessionMap& session, double time_s, const std::string& name,
                    bool replace) {
  AddSettings options;
  options.name = name;
  options.replace = replace;
  AddReport report;
  {
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

DiffMap diffTimes(const TemporalMap& map, double t1_s, double t2_s, const std::string& mode, double alpha,
                  int neighbourhood_voxels, double min_shift_voxels) {
  const DiffSettings settings = diffSettings(mode, alpha, neighbourhood_voxels, min_shift_voxels);
  py::gil_scoped_release release;
  return diff(map, t1_s, t2_s, settings);
}

}  // namespace

void bindTemporal(py::module_& m) {
  py::class_<TemporalMap>(m, "TemporalMap", "The 4D map: every observed state of a place, session by session.")
      .def(py::init([](double resolution_m) { return TemporalMap(resolution_m); }), py::arg("resolution_m") = 0.05,
           "An empty 4D map.")
      .def_static(
          "open",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return io::readTemporalMap(path);
          },
          py::arg("path"), "Reads a 4D map file (.cmap). Raises IoError or FormatError naming the file.")
      .def(
          "save",
          [](const TemporalMap& map, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            io::writeTemporalMap(path, map, nlohmann::json::object());
          },
          py::arg("path"), "Writes the 4D map file (.cmap), atomically.")
      .def_property_readonly("resolution_m", &TemporalMap::resolution_m, "Voxel edge length in metres.")
      .def_property_readonly(
          "times_s", [](const TemporalMap& map) { return vectorArray(map.times()); },
          "Session times (seconds since the epoch), increasing, as a float64 array.")
      .def("add", &addSession, py::arg("session"), py::arg("time_s"), py::arg("name") = "", py::arg("replace") = false,
           "Adds a SessionMap observed at time_s (epoch seconds); returns what changed in the map. Raises "
           "UsageError for a time already stored unless replace=True.")
      .def(
          "snapshot",
          [](const TemporalMap& map, double time_s) {
            py::gil_scoped_release release;
            return map.snapshot(time_s);
          },
          py::arg("time_s"), "The SessionMap as most recently observed at time_s (empty before the first session).")
      .def("history", &historyOf, py::arg("point"),
           "The history of the voxel containing `point` (3,): a list of (time_s, state), empty when never "
           "observed.")
      .def("diff", &diffTimes, py::arg("t1_s"), py::arg("t2_s"), py::arg("mode") = "hard", py::arg("alpha") = -1.0,
           py::arg("neighbourhood_voxels") = 0, py::arg("min_shift_voxels") = 0.0,
           "What changed from the state at t1_s to the state at t2_s: the diff of the two snapshots, visiting "
           "only what changed in between. Settings as chronomap.diff.")
      .def("__len__", &TemporalMap::sessionCount)
      .def("__eq__", [](const TemporalMap& a, const TemporalMap& b) { return a == b; });
}

}  // namespace chronomap::python
