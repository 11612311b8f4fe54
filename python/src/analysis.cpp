// diff and segment: what changed between two session maps, and which objects.

#include <string>

#include <nlohmann/json.hpp>

#include "bindings.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"

namespace chronomap::python {

DiffSettings diffSettings(const std::string& mode, double alpha, int neighbourhood_voxels, double min_shift_voxels,
                          int kept_surface_radius_voxels, double kept_surface_share, int dark_surface_radius_voxels,
                          double dark_surface_brightness, double dark_surface_contrast, double dark_surface_share,
                          double shift_plane_ratio) {
  DiffSettings settings;
  settings.mode = parseDiffMode(mode);
  settings.alpha = alpha;
  settings.neighbourhood_voxels = neighbourhood_voxels;
  settings.min_shift_voxels = min_shift_voxels;
  settings.kept_surface_radius_voxels = kept_surface_radius_voxels;
  settings.kept_surface_share = kept_surface_share;
  settings.dark_surface_radius_voxels = dark_surface_radius_voxels;
  settings.dark_surface_brightness = dark_surface_brightness;
  settings.dark_surface_contrast = dark_surface_contrast;
  settings.dark_surface_share = dark_surface_share;
  settings.shift_plane_ratio = shift_plane_ratio;
  return settings;
}

namespace {

DiffMap diffPy(const SessionMap& before, const SessionMap& after, const std::string& mode, double alpha,
               int neighbourhood_voxels, double min_shift_voxels, int kept_surface_radius_voxels,
               double kept_surface_share, int dark_surface_radius_voxels, double dark_surface_brightness,
               double dark_surface_contrast, double dark_surface_share, double shift_plane_ratio) {
  const DiffSettings settings =
      diffSettings(mode, alpha, neighbourhood_voxels, min_shift_voxels, kept_surface_radius_voxels, kept_surface_share,
                   dark_surface_radius_voxels, dark_surface_brightness, dark_surface_contrast, dark_surface_share,
                   shift_plane_ratio);
  py::gil_scoped_release release;
  return diff(before, after, settings);
}

py::list segmentPy(const DiffMap& changes, const std::string& connectivity, double colour_tolerance,
                   uint64_t min_voxels, double min_value) {
  SegmentSettings settings;
  settings.connectivity = parseConnectivity(connectivity);
  settings.colour_tolerance = colour_tolerance;
  settings.min_voxels = min_voxels;
  settings.min_value = min_value;
  Segmentation result;
  {
    py::gil_scoped_release release;
    result = segment(changes, settings);
  }
  py::list out;
  for (Component& c : result.components) out.append(py::cast(std::move(c)));
  return out;
}

/// The objects as the command line prints them (changedObjectsJson), as Python lists and dicts.
py::object objectsToPython(const Changes& changes) {
  return py::module_::import("json").attr("loads")(changedObjectsJson(changes.objects).dump());
}

py::object changesOfSessions(const SessionMap& before, const SessionMap& after, const std::string& preset) {
  const ChangeSettings settings = changeSettingsNamed(preset);
  Changes result;
  {
    py::gil_scoped_release release;
    result = findChanges(before, after, settings);
  }
  return objectsToPython(result);
}

py::object changesOfTimes(const TemporalMap& map, const py::handle& t0, const py::handle& t1,
                          const std::string& preset) {
  const ChangeSettings settings = changeSettingsNamed(preset);
  const double t0_s = toSeconds(t0, "t0"), t1_s = toSeconds(t1, "t1");
  Changes result;
  {
    const ObjectLock lock(&map);
    py::gil_scoped_release release;
    result = findChanges(map, t0_s, t1_s, settings);
  }
  return objectsToPython(result);
}

template <class T, class Fn>
py::array_t<T> perCell(const DiffMap& d, Fn&& fn) {
  std::vector<T> values;
  values.reserve(d.cells().size());
  for (const ChangeCell& c : d.cells()) values.push_back(static_cast<T>(fn(c)));
  return vectorArray(std::move(values));
}

py::array_t<double> cellCenters(const DiffMap& d) {
  std::vector<Eigen::Vector3d> centers;
  centers.reserve(d.cells().size());
  for (const ChangeCell& c : d.cells()) centers.push_back(d.grid().centerOf(c.key, c.level));
  return pointsArray(std::move(centers));
}

void bindDiffMap(py::module_& m) {
  py::class_<DiffMap>(m, "DiffMap",
                      "What changed between two maps: cells (unit voxels or uniform cubes) in Morton order.")
      .def_property_readonly("resolution_m", &DiffMap::resolution_m)
      .def_property_readonly("mode", [](const DiffMap& d) { return std::string(toString(d.settings().mode)); })
      .def("__len__", [](const DiffMap& d) { return d.cells().size(); })
      .def("changed_centers", &cellCenters, "Centres of the cells, (N, 3) float64 metres.")
      .def(
          "kinds", [](const DiffMap& d) { return perCell<int8_t>(d, [](const ChangeCell& c) { return c.kind; }); },
          "Kind of each cell, (N,) int8: APPEARED, VANISHED or UNCHANGED (continuous mode).")
      .def(
          "levels", [](const DiffMap& d) { return perCell<int8_t>(d, [](const ChangeCell& c) { return c.level; }); },
          "Level of each cell, (N,) int8: 0 a voxel, k a cube of 2^k voxels per axis.")
      .def(
          "values", [](const DiffMap& d) { return perCell<float>(d, [](const ChangeCell& c) { return c.value; }); },
          "|P1 - P2| of each cell, (N,) float32.")
      .def(
          "voxel_count",
          [](const DiffMap& d, const py::object& kind) {
            return kind.is_none() ? d.voxelCount() : d.voxelCount(static_cast<ChangeKind>(kind.cast<int>()));
          },
          py::arg("kind") = py::none(), "Unit voxels in cells of this kind (all kinds when None).");
}

void bindComponent(py::module_& m) {
  py::class_<Component>(m, "Component", "One connected object of a diff.")
      .def_readonly("id", &Component::id, "1.. in order of decreasing size")
      .def_property_readonly("kind", [](const Component& c) { return std::string(toString(c.kind)); },
                             "'appeared' or 'vanished' (or 'unchanged')")
      .def_readonly("voxels", &Component::voxels, "unit voxels")
      .def_readonly("volume_m3", &Component::volume_m3)
      .def_property_readonly("bbox_min_m", [](const Component& c) { return vector3Array(c.bbox_min_m); })
      .def_property_readonly("bbox_max_m", [](const Component& c) { return vector3Array(c.bbox_max_m); })
      .def_property_readonly("centroid_m", [](const Component& c) { return vector3Array(c.centroid_m); })
      .def_property_readonly("mean_color",
                             [](const Component& c) { return py::make_tuple(c.mean_colour.r, c.mean_colour.g,
                                                                            c.mean_colour.b); })
      .def_property_readonly("cells", [](const Component& c) { return vectorArray(c.cells); },
                             "indices into the diff's cells, increasing")
      .def("__repr__", [](const Component& c) {
        std::string r("<Component id=");
        r.append(std::to_string(c.id)).append(" kind=").append(toString(c.kind));
        return r.append(" voxels=").append(std::to_string(c.voxels)).append(">");
      });
}

}  // namespace

void bindAnalysis(py::module_& m) {
  m.attr("APPEARED") = static_cast<int>(ChangeKind::Appeared);
  m.attr("VANISHED") = static_cast<int>(ChangeKind::Vanished);
  m.attr("UNCHANGED") = static_cast<int>(ChangeKind::Unchanged);
  bindDiffMap(m);
  bindComponent(m);
  m.def("diff", &diffPy, py::arg("before"), py::arg("after"), py::arg("mode") = "hard", py::arg("alpha") = -1.0,
        py::arg("neighbourhood_voxels") = 0, py::arg("min_shift_voxels") = 0.0,
        py::arg("kept_surface_radius_voxels") = 0, py::arg("kept_surface_share") = DiffSettings::kDefaultKeptSurfaceShare,
        py::arg("dark_surface_radius_voxels") = 0,
        py::arg("dark_surface_brightness") = DiffSettings::kDefaultDarkSurfaceBrightness,
        py::arg("dark_surface_contrast") = DiffSettings::kDefaultDarkSurfaceContrast,
        py::arg("dark_surface_share") = DiffSettings::kDefaultDarkSurfaceShare, py::arg("shift_plane_ratio") = 0.0,
        "What changed from `before` to `after` (two SessionMaps of one resolution). mode: 'hard', "
        "'threshold', 'band' or 'continuous'; alpha < 0 takes the mode's default. kept_surface_radius_voxels "
        "(0: off; 3 recommended) drops a change in front of a surface the other map still sees unchanged "
        "(docs/changes.md, the weak-change rule); dark_surface_radius_voxels (0: off; 2 as measured) drops an "
        "object lying within that many voxels of the other map's surface when at least dark_surface_share of its "
        "voxels are dark and darker than the other map's around them (the dark-surface rule); shift_plane_ratio "
        "(0: off; 0.15 recommended) makes min_shift_voxels count only a flat surface's move across itself.");
  m.def("segment", &segmentPy, py::arg("diff"), py::arg("connectivity") = "face", py::arg("color_tolerance") = -1.0,
        py::arg("min_voxels") = 1, py::arg("min_value") = 0.5,
        "Connected components of a DiffMap, largest first: a list of Component.");
  const char* changes_doc =
      "What changed, and which objects (docs/changes.md): the list `chronomap diff --json` prints as "
      "\"objects\", from the same library call (findChanges). Each object is a dict: id, kind ('appeared', "
      "'vanished' or 'moved'), voxels, centroid, size, bbox_min, bbox_max (metres), colour (r, g, b), "
      "components, and for a move from and to ({voxels, centroid, size}) and distance_m. preset: "
      "'recommended' (the default, as chronomap diff) or 'raw' (the plain hard diff, every component, no moves).";
  m.def("changes", &changesOfSessions, py::arg("before"), py::arg("after"), py::arg("preset") = "recommended",
        changes_doc);
  m.def("changes", &changesOfTimes, py::arg("map"), py::arg("t0"), py::arg("t1"), py::arg("preset") = "recommended",
        "The same for a TemporalMap from its state at t0 to its state at t1 (epoch seconds, ISO-8601 strings or datetimes).");
}

}  // namespace chronomap::python
