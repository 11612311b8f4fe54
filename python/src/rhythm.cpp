// Temporal models (analysis/rhythm.h) and costmaps (analysis/costmap.h) from Python.

#include <filesystem>
#include <string>

#include "bindings.h"
#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/io/rhythm_file.h"

namespace chronomap::python {

namespace {

RhythmModels fit(const TemporalMap& map, const py::object& from, const py::object& to, uint32_t min_changes) {
  const double inf = std::numeric_limits<double>::infinity();
  const double from_s = from.is_none() ? -inf : toSeconds(from, "from_time");
  const double to_s = to.is_none() ? inf : toSeconds(to, "to_time");
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
            return io::readRhythmModels(path);
          },
          py::arg("path"), "Reads a model saved by save() or `chronomap predict --save-rhythm`.")
      .def(
          "save",
          [](const RhythmModels& r, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            io::writeRhythmModels(path, r);
          },
          py::arg("path"), "Writes the model (.rhythm), atomically.")
      .def("__len__", [](const RhythmModels& r) { return r.voxels.size(); })
      .def_property_readonly("sessions", [](const RhythmModels& r) { return r.sessions; }, "Learning sessions.")
      .def_property_readonly("bytes", &RhythmModels::bytes, "Bytes of the saved model.")
      .def("predict", &predictPoints, py::arg("points"), py::arg("time"), py::arg("model") = "combined",
           "Probability of occupancy at `time` of the voxel containing each of the (N, 3) points: (N,) float64, NaN "
           "where no model was fitted (the voxel never changed while learning).")
      .def(
          "predict_map",
          [](const RhythmModels& r, const TemporalMap& map, const py::handle& time, const std::string& model) {
            const double t = toSeconds(time, "time");
            const RhythmModel which = parseRhythmModel(model);
            py::gil_scoped_release release;
            return predictMap(map, r, which, t);
          },
          py::arg("map"), py::arg("time"), py::arg("model") = "combined",
          "The SessionMap predicted at `time`, as `chronomap predict` writes it: modelled voxels carry the "
          "model's probability, the rest their last observed state.");
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
