// Temporal models (analysis/rhythm.h) and costmaps (analysis/costmap.h) from Python.

#include <filesystem>
#include <string>

#include "bindings.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/fitted_on.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/store/rhythm_file.h"

namespace chronomap::python {

namespace {

RhythmModels fit(const TemporalMap& map, const py::object& from, const py::object& to, uint32_t min_changes) {
  const double inf = std::numeric_limits<double>::infinity();
  const double from_s = from.is_none() ? -inf : toSeconds(from, "from_time");
  const double to_s = to.is_none() ? inf : toSeconds(to, "to_time");
  const ObjectLock lock(&map);
  py::gil_scoped_release release;
  return fitRhythm(map, from_s, to_s, min_changes);
}

py::array_t<double> predictPoints(const RhythmModels& models, const py::handle& points, const py::handle& time,
                                  const std::string& model) {
  const std::vector<Eigen::Vector3d> p = toPoints(points, "points");
  const double t = toSeconds(time, "time");
  const RhythmModel m = parseRhythmModel(model);
  const KeyGrid grid(models.resolution_m);
  std::vector<double> out(p.size(), std::numeric_limits<double>::quiet_NaN());
  {
    py::gil_scoped_release release;
    for (size_t i = 0; i < p.size(); ++i) {
      if (const auto key = grid.keyOf(p[i])) {
        if (const VoxelRhythm* v = models.find(*key)) out[i] = RhythmModels::predict(*v, m, t);
      }
    }
  }
  return vectorArray(std::move(out));
}

py::tuple costmapPy(const SessionMap& map, double z_min_m, double z_max_m, double robot_radius_m,
                    double change_weight, const RhythmModels* models) {
  CostmapSettings s;
  s.z_min_m = z_min_m;
  s.z_max_m = z_max_m;
  s.robot_radius_m = robot_radius_m;
  s.change_weight = change_weight;
  Costmap c;
  {
    py::gil_scoped_release release;
    c = costmap(map, s, models);
  }
  const auto h = static_cast<py::ssize_t>(c.height), w = static_cast<py::ssize_t>(c.width);
  py::array cost = vectorArray(std::move(c.cost)).attr("reshape")(h, w);
  return py::make_tuple(cost, py::make_tuple(c.origin_m.x(), c.origin_m.y()), c.resolution_m);
}

/// A colour model with the resolution of the map it was fitted to, for point queries.
struct PyColourModel {
  ColourModel model;
  double resolution_m = 0.05;
};

ColourModel fitColourPy(const TemporalMap& map, const py::object& from, const py::object& to, int components) {
  const double inf = std::numeric_limits<double>::infinity();
  const double from_s = from.is_none() ? -inf : toSeconds(from, "from_time");
  const double to_s = to.is_none() ? inf : toSeconds(to, "to_time");
  ColourSettings s;
  s.components = components;
  const ObjectLock lock(&map);
  py::gil_scoped_release release;
  return fitColour(map, from_s, to_s, s);
}

py::array_t<double> predictColours(const ColourModel& model, double resolution_m, const py::handle& points,
                                   const py::handle& time) {
  const std::vector<Eigen::Vector3d> p = toPoints(points, "points");
  const double hour = hourOfDay(toSeconds(time, "time"));
  const KeyGrid grid(resolution_m);
  std::vector<double> out(p.size() * 3, std::numeric_limits<double>::quiet_NaN());
  for (size_t i = 0; i < p.size(); ++i) {
    const auto key = grid.keyOf(p[i]);
    if (!key) continue;
    const auto v = model.find(*key);
    if (!v) continue;
    const std::array<double, 3> c = model.predict(*v, hour);
    for (size_t k = 0; k < 3; ++k) out[i * 3 + k] = c[k];
  }
  return vectorArray(std::move(out)).attr("reshape")(static_cast<py::ssize_t>(p.size()), 3);
}

}  // namespace

void bindRhythm(py::module_& m) {
  py::class_<RhythmModels>(m, "RhythmModels",
                           "Temporal models of every voxel that changed while learning (docs/rhythm.md): latest, mean, "
                           "markov, periodic, hourly, combined.")
      .def_static(
          "fit", &fit, py::arg("map"), py::arg("from_time") = py::none(), py::arg("to_time") = py::none(),
          py::arg("min_changes") = 1,
          "Fits every model to the sessions of `map` (a TemporalMap) in [from_time, to_time] (None: all), for the "
          "voxels that changed at least min_changes times among them. Sessions that did not observe a voxel are "
          "no evidence.")
      .def_static(
          "open",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return readRhythmModels(path);
          },
          py::arg("path"), "Reads a model saved by save() or `chronomap predict --save-rhythm`.")
      .def(
          "save",
          [](const RhythmModels& r, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            writeRhythmModels(path, r);
          },
          py::arg("path"), "Writes the model (.rhythm), atomically.")
      .def("__len__", [](const RhythmModels& r) { return r.voxels.size(); })
      .def_property_readonly("sessions", [](const RhythmModels& r) { return r.sessions; }, "Learning sessions.")
      .def_property_readonly("bytes", &RhythmModels::bytes, "Bytes of the saved model.")
      .def_property_readonly(
          "groups", [](const RhythmModels& r) { return r.groups.size(); },
          "Objects (voxels that change together) whose pooled hourly profile some voxel's combined model uses.")
      .def("predict", &predictPoints, py::arg("points"), py::arg("time"), py::arg("model") = "combined",
           "Probability of occupancy at `time` of the voxel containing each of the (N, 3) points: (N,) float64, NaN "
           "where no model was fitted (the voxel never changed while learning).")
      .def(
          "predict_map",
          [](const RhythmModels& r, const TemporalMap& map, const py::handle& time, const std::string& model,
             bool allow_other_map) {
            const double t = toSeconds(time, "time");
            const RhythmModel which = parseRhythmModel(model);
            const ObjectLock lock(&map);
            // The model must have been fitted on this map, as for `chronomap predict --rhythm`.
            const std::string warning = checkFittedOn(
                r, map, {"the model", "the map", "fit one on this map with RhythmModels.fit(map)",
                         "allow_other_map=True", allow_other_map});
            if (!warning.empty() && PyErr_WarnEx(PyExc_UserWarning, warning.c_str(), 1) < 0) {
              throw py::error_already_set();  // warnings turned into errors
            }
            py::gil_scoped_release release;
            return predictMap(map, r, which, t);
          },
          py::arg("map"), py::arg("time"), py::arg("model") = "combined", py::arg("allow_other_map") = false,
          "The SessionMap predicted at `time`, as `chronomap predict` writes it: modelled voxels carry the "
          "model's probability, the rest their last observed state. A model fitted on another map (other "
          "sessions, another fingerprint, another resolution) raises ValueError; allow_other_map=True warns "
          "instead (another resolution is always refused).");
  py::class_<PyColourModel>(m, "ColourModel",
                            "Colour by time of day (docs/colour.md): per voxel weights under a few light curves of the "
                            "day shared by the map, learned from the colour changes a 4D map keeps.")
      .def_static(
          "fit",
          [](const TemporalMap& map, const py::object& from, const py::object& to, int components) {
            return PyColourModel{fitColourPy(map, from, to, components), map.resolution_m()};
          },
          py::arg("map"), py::arg("from_time") = py::none(), py::arg("to_time") = py::none(), py::arg("components") = 2,
          "Fits the model to the sessions of `map` (a TemporalMap made with color_distance > 0) in [from_time, "
          "to_time] (None: all).")
      .def_static(
          "open",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            ColourModel model = readColourModel(path);
            const double resolution_m = model.resolution_m;
            return PyColourModel{std::move(model), resolution_m};
          },
          py::arg("path"), "Reads a model saved by save() or `chronomap predict --save-colour`.")
      .def(
          "save",
          [](const PyColourModel& c, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            writeColourModel(path, c.model);
          },
          py::arg("path"), "Writes the model (.colour), atomically.")
      .def("__len__", [](const PyColourModel& c) { return c.model.keys.size(); })
      .def_property_readonly("components", [](const PyColourModel& c) { return c.model.components; })
      .def_property_readonly("bytes", [](const PyColourModel& c) { return c.model.bytes(); },
                             "Bytes of the model: per voxel its key and weights, and the curves.")
      .def_property_readonly("rms_error", [](const PyColourModel& c) { return c.model.rms_error; },
                             "RMS of the fit per channel over the learning observations, 8-bit units.")
      .def(
          "curves",
          [](const PyColourModel& c, double hour) {
            std::vector<double> out;
            for (int j = 0; j < c.model.components; ++j) {
              for (int k = 0; k < 3; ++k) out.push_back(c.model.curve(j, k, hour));
            }
            return vectorArray(std::move(out)).attr("reshape")(c.model.components, 3);
          },
          py::arg("hour"), "The light curves at `hour` (0..24): (components, 3) float64, each curve's peak 1.")
      .def(
          "predict",
          [](const PyColourModel& c, const py::handle& points, const py::handle& time) {
            return predictColours(c.model, c.resolution_m, points, time);
          },
          py::arg("points"), py::arg("time"),
          "Colour (0..255, not clamped) at the hour of `time` of the voxel containing each of the (N, 3) points: (N, "
          "3) float64, NaN where the voxel has no model.")
      .def(
          "recolour",
          [](const PyColourModel& c, const SessionMap& map, const py::handle& time) {
            const double t = toSeconds(time, "time");
            py::gil_scoped_release release;
            return recolour(map, c.model, t);
          },
          py::arg("session_map"), py::arg("time"),
          "`session_map` with every modelled voxel's colour set to the model's at the hour of `time` (as "
          "`chronomap predict --colour`).");
  m.def(
      "costmap",
      [](const SessionMap& map, double z_min_m, double z_max_m, double robot_radius_m, double change_weight,
         const RhythmModels* models) { return costmapPy(map, z_min_m, z_max_m, robot_radius_m, change_weight, models); },
      py::arg("session_map"), py::arg("z_min_m") = 0.05, py::arg("z_max_m") = 1.8, py::arg("robot_radius_m") = 0.3,
      py::arg("change_weight") = 0.5, py::arg("models") = py::none(),
      "A navigation costmap of a SessionMap over a height band, as `chronomap costmap` computes it: returns "
      "(cost (H, W) int8 with -1 unknown, 0..98 cost, 99 inscribed, 100 lethal, row 0 the lowest y; origin_m "
      "(x, y); resolution_m).");
}

}  // namespace chronomap::python
