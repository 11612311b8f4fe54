// SessionMap: open/save, resolution, bounds, voxel states of points, occupied voxels as arrays.

#include <filesystem>
#include <limits>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "bindings.h"
#include "chronomap/store/cmap.h"
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

/// The counters of the voxel containing each point (nothing for points outside or unobserved).
std::vector<std::optional<VoxelCounters>> countersAt(const SessionMap& map, const std::vector<Eigen::Vector3d>& p) {
  std::vector<std::optional<VoxelCounters>> out(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    if (const auto key = map.grid().keyOf(p[i])) out[i] = map.find(*key);
  }
  return out;
}

py::array_t<double> probabilitiesOf(const SessionMap& map, const py::handle& points) {
  const std::vector<Eigen::Vector3d> p = toPoints(points, "points");
  std::vector<double> out(p.size());
  {
    py::gil_scoped_release release;
    const auto counters = countersAt(map, p);
    for (size_t i = 0; i < p.size(); ++i) {
      out[i] = counters[i] ? counters[i]->probability() : std::numeric_limits<double>::quiet_NaN();
    }
  }
  return vectorArray(std::move(out));
}

py::dict countersOf(const SessionMap& map, const py::handle& points) {
  const std::vector<Eigen::Vector3d> p = toPoints(points, "points");
  std::vector<float> length(p.size(), 0.0f);
  std::vector<uint32_t> hits(p.size(), 0);
  std::vector<int8_t> states(p.size(), static_cast<int8_t>(VoxelState::Unknown));
  std::vector<Rgb> colours(p.size());
  std::vector<double> offsets(3 * p.size(), 0.0);
  {
    py::gil_scoped_release release;
    const auto counters = countersAt(map, p);
    for (size_t i = 0; i < p.size(); ++i) {
      if (!counters[i]) continue;
      const VoxelCounters& c = *counters[i];
      length[i] = c.length_m;
      hits[i] = c.hits;
      states[i] = static_cast<int8_t>(c.state());
      colours[i] = c.meanColour();
      for (int a = 0; a < 3; ++a) offsets[3 * i + a] = c.meanOffset(a);
    }
  }
  py::dict d;
  d["length_m"] = vectorArray(std::move(length));
  d["hits"] = vectorArray(std::move(hits));
  d["state"] = vectorArray(std::move(states));
  d["mean_color"] = coloursArray(std::move(colours));
  d["mean_offset_voxels"] = vectorArray(std::move(offsets)).attr("reshape")(static_cast<py::ssize_t>(p.size()), 3);
  return d;
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
            return readSessionMap(path);
          },
          py::arg("path"), "Reads a session map file (.cmap). Raises IoError or FormatError naming the file.")
      .def(
          "save",
          [](const SessionMap& map, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            writeSessionMap(path, map, nlohmann::json::object());
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
          "occupied_colors", [](const SessionMap& map) { return coloursArray(occupiedCentres(map).colours); },
          "Mean colours of the occupied voxels, (N, 3) uint8, in the order of occupied_centers().")
      .def("probability", &probabilitiesOf, py::arg("points"),
           "Occupancy probability 1 - exp(-hits / length) of the voxel containing each of the (N, 3) points: an "
           "(N,) float64 array, NaN where the voxel was never observed (or lies outside the map).")
      .def("counters", &countersOf, py::arg("points"),
           "The counters of the voxel containing each of the (N, 3) points, as a dict of arrays: length_m "
           "(N,) float32 (summed ray length), hits (N,) uint32 (rays that ended there), state (N,) int8, "
           "mean_color (N, 3) uint8, mean_offset_voxels (N, 3) float64 (where the surface lies in the voxel, "
           "from its centre). Zeros and UNKNOWN where never observed; a voxel inside a compressed free cube "
           "gets its even share of the cube's sums.")
      .def(
          "free_centers",
          [](const SessionMap& map) {
            FreeLeaves free = freeLeaves(map);
            return py::make_tuple(pointsArray(std::move(free.centers_m)), vectorArray(std::move(free.sizes_m)));
          },
          "The known-free leaves as (centers (N, 3) float64 metres, sizes_m (N,) float64): unit voxels and "
          "compressed free cubes, each once with its edge length, in Morton order.")
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
