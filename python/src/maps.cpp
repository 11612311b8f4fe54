// SessionMap: open/save, resolution, bounds, voxel states of points, occupied voxels as arrays.

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "bindings.h"
#include "chronomap/io/cmap.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/octree/voxel_queries.h"

namespace chronomap::python {

namespace {

py::array_t<int8_t> statesOf(const SessionMap& map, const py::handle& points) {
  const std::vector<Eigen::Vector3d> p = toPoints(points, "points");
  std::vector<int8_t> states(p.size(), static_cast<int8_t>(VoxelState::Unknown));
  {
    py::gil_scoped_release release;
    for (size_t i = 0; i < p.size(); ++i) {
      if (const auto key = map.grid().keyOf(p[i])) states[i] = static_cast<int8_t>(map.stateOf(*key));
    }
  }
  return vectorArray(std::move(states));
}

py::object boundsOf(const SessionMap& map) {
  const auto bounds = knownBounds(map);
  if (!bounds) return py::none();
  return py::make_tuple(vector3Array(bounds->min_m), vector3Array(bounds->max_m));
}

py::dict countsOf(const SessionMap& map) {
  const SessionMapCounts c = map.counts();
  py::dict d;
  d["inner_nodes"] = c.inner_nodes;
  d["leaves"] = c.leaves;
  d["compressed_leaves"] = c.compressed_leaves;
  d["occupied_voxels"] = c.occupied_voxels;
  d["free_voxels"] = c.free_voxels;
  return d;
}

}  // namespace

void bindMaps(py::module_& m) {
  m.attr("UNKNOWN") = static_cast<int>(VoxelState::Unknown);
  m.attr("FREE") = static_cast<int>(VoxelState::Free);
  m.attr("OCCUPIED") = static_cast<int>(VoxelState::Occupied);

  py::class_<SessionMap>(m, "SessionMap", "The map of one recording: an octree of voxel counters.")
      .def(py::init<double>(), py::arg("resolution_m") = 0.05, "An empty map with voxels of this size.")
      .def_static(
          "open",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return io::readSessionMap(path);
          },
          py::arg("path"), "Reads a session map file (.cmap). Raises IoError or FormatError naming the file.")
      .def(
          "save",
          [](const SessionMap& map, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            io::writeSessionMap(path, map, nlohmann::json::object());
          },
          py::arg("path"), "Writes the map as a session map file (.cmap), atomically.")
      .def_property_readonly("resolution_m", &SessionMap::resolution_m, "Voxel edge length in metres.")
      .def("bounds_m", &boundsOf, "(min, max) corners of the known voxels in metres, or None when empty.")
      .def("state", &statesOf, py::arg("points"),
           "State of the voxel containing each of the (N, 3) points: an (N,) int8 array of UNKNOWN, FREE or "
           "OCCUPIED (UNKNOWN outside the map).")
      .def(
          "occupied_centers", [](const SessionMap& map) { return pointsArray(occupiedCentres(map).centers_m); },
          "Centres of the occupied voxels, (N, 3) float64 metres, in Morton order.")
      .def(
          "occupied_colors", [](const SessionMap& map) { return colorsArray(occupiedCentres(map).colors); },
          "Mean colours of the occupied voxels, (N, 3) uint8, in the order of occupied_centers().")
      .def("counts", &countsOf, "Nodes and voxel states the map holds.")
      .def_property_readonly("memory_bytes", &SessionMap::memoryBytes, "Bytes of node storage in use.")
      .def("empty", &SessionMap::empty, "True when nothing was ever added.")
      .def("__eq__", [](const SessionMap& a, const SessionMap& b) { return a == b; })
      .def("__repr__", [](const SessionMap& map) {
        std::string r("<SessionMap resolution_m=");
        r.append(std::to_string(map.resolution_m())).append(" leaves=").append(std::to_string(map.leafCount()));
        return r.append(">");
      });
}

}  // namespace chronomap::python
