// integrate_dataset (integrateDataset) and the incremental Integrator
// (IncrementalIntegrator) fed from numpy arrays.

#include <memory>
#include <optional>
#include <span>
#include <string>

#include "bindings.h"
#include "chronomap/core/camera.h"
#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "chronomap/integrate/incremental.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/depth_image.h"
#include "chronomap/ingest/png.h"
#include "chronomap/pipeline/session.h"

namespace chronomap::python {

namespace {

/// carve_level: "auto" (kCarveAuto) or a level from 0 to kMaxCarveLevel (`--carve-level`).
int toCarveLevel(const py::object& level) {
  if (py::isinstance<py::str>(level) && level.cast<std::string>() == "auto") return kCarveAuto;
  if (py::isinstance<py::int_>(level) && !py::isinstance<py::bool_>(level)) {
    const long v = level.cast<long>();
    if (v >= 0 && v <= kMaxCarveLevel) return static_cast<int>(v);
  }
  throw py::value_error("carve_level must be 'auto' or a level from 0 to " + std::to_string(kMaxCarveLevel) +
                        ", not " + py::repr(level).cast<std::string>());
}

SessionMap integrateDatasetPy(const std::filesystem::path& path, double resolution_m, bool fast, double max_range_m,
                              int threads, const std::string& format, std::optional<double> depth_scale,
                              const py::object& progress, bool carve_beyond_range, const py::object& carve_level,
                              const py::object& up, double depth_edges) {
  SessionSettings settings;
  settings.integrator.depth_edge_ratio = depth_edges;
  settings.up = toUpSettings(up);
  settings.integrator.carve_level = toCarveLevel(carve_level);
  settings.resolution_m = resolution_m;
  settings.integrator.fast = fast;
  settings.integrator.max_range_m = max_range_m;
  settings.integrator.carve_beyond_range = carve_beyond_range;
  settings.integrator.threads = threads;
  settings.dataset.format = parseRecordingFormat(format);
  settings.dataset.depth_scale = depth_scale;
  LongCall call(progress);
  const Progress report = call.progress();
  IntegratedSession session = call.run([&] { return integrateDataset(path, settings, {}, report); });
  for (const std::string& w : session.warnings) {
    const std::string text = path.string() + ": " + w;
    if (PyErr_WarnEx(PyExc_UserWarning, text.c_str(), 1) < 0) throw py::error_already_set();  // warnings as errors
  }
  return std::move(session.map);
}

/// (fx, fy, cx, cy) or a 3x3 K matrix. @throw UsageError (a ValueError) naming the values when
/// intrinsicsValid refuses them.
CameraIntrinsics toIntrinsics(const py::handle& h) {
  const py::array a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(h);
  if (!a) throw py::type_error("intrinsics: expected (fx, fy, cx, cy) or a 3x3 matrix of numbers");
  const auto* p = static_cast<const double*>(a.data());
  CameraIntrinsics k;
  if (a.size() == 4 && a.ndim() == 1) {
    k = {p[0], p[1], p[2], p[3]};
  } else if (a.ndim() == 2 && a.shape(0) == 3 && a.shape(1) == 3) {
    k = {p[0], p[4], p[2], p[5]};
  } else {
    throw py::value_error("intrinsics: expected (fx, fy, cx, cy) or a 3x3 matrix");
  }
  // The check of every reader and back-projection (core/camera.h; a negative focal length
  // would mirror the map), refused as a bad argument.
  if (!intrinsicsValid(k)) {
    try {
      checkIntrinsics(k, "add_frame");
    } catch (const DataError& e) {
      throw UsageError(e.what());
    }
  }
  return k;
}

/// The depth image as an organized cloud in the camera frame: uint16 with `depth_scale` units
/// per metre, or float32 metres.
PointCloud depthCloud(const py::handle& h, const ImageRgb* rgb, const CameraIntrinsics& k, double depth_scale) {
  const py::array any = py::array::ensure(h);
  if (!any) throw py::type_error("depth: expected an (H, W) array");
  if (any.ndim() != 2) throw py::value_error("depth: expected shape (H, W)");
  const auto height = static_cast<uint32_t>(any.shape(0)), width = static_cast<uint32_t>(any.shape(1));
  if (any.dtype().is(py::dtype::of<uint16_t>())) {
    const auto a = py::array_t<uint16_t, py::array::c_style | py::array::forcecast>::ensure(any);
    ImageU16 depth{width, height, std::vector<uint16_t>(a.data(), a.data() + a.size())};
    py::gil_scoped_release release;
    return depthToCloud(depth, rgb, k, depth_scale, "add_frame");
  }
  if (any.dtype().is(py::dtype::of<float>())) {
    const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(any);
    py::gil_scoped_release release;
    return depthMetresToCloud(std::span<const float>(a.data(), static_cast<size_t>(a.size())), width, height, rgb,
                                  k, "add_frame");
  }
  std::string msg("depth: expected uint16 (with depth_scale) or float32 metres, got dtype ");
  throw py::type_error(msg.append(py::str(any.dtype()).cast<std::string>()));
}

/// Checked and re-orthonormalised as dataset readers do. @throw DataError when not rigid.
Eigen::Isometry3d toPose(const py::handle& h, const char* name) { return poseFromMatrix(toMatrix4(h, name), name); }

py::array_t<uint16_t> readDepthPng(const std::filesystem::path& path) {
  ImageU16 img;
  {
    py::gil_scoped_release release;
    img = readPngU16(path);
  }
  const auto h = static_cast<py::ssize_t>(img.height), w = static_cast<py::ssize_t>(img.width);
  return vectorArray(std::move(img.pixels)).attr("reshape")(h, w);  // a view, no copy
}

py::array_t<uint8_t> readColourPng(const std::filesystem::path& path) {
  ImageRgb img;
  {
    py::gil_scoped_release release;
    img = readPngRgb(path);
  }
  const auto h = static_cast<py::ssize_t>(img.height), w = static_cast<py::ssize_t>(img.width);
  return coloursArray(std::move(img.pixels)).attr("reshape")(h, w, 3);  // a view, no copy
}

void addFrame(IncrementalIntegrator& integrator, const py::handle& depth, const py::handle& intrinsics,
              const py::handle& T_world_camera, const py::object& rgb, double depth_scale) {
  const CameraIntrinsics k = toIntrinsics(intrinsics);
  Frame frame;
  frame.T_world_sensor = toPose(T_world_camera, "T_world_camera");
  std::optional<ImageRgb> colour;
  if (!rgb.is_none()) colour = toRgbImage(rgb, "rgb");
  frame.cloud = depthCloud(depth, colour ? &*colour : nullptr, k, depth_scale);
  frame.source = "add_frame";
  const ObjectLock lock(&integrator);
  py::gil_scoped_release release;
  integrator.add(frame);
}

void addPoints(IncrementalIntegrator& integrator, const py::handle& points_world, const py::handle& origin,
               const py::object& colours) {
  const std::vector<Eigen::Vector3d> points = toPoints(points_world, "points_world");
  const Eigen::Vector3d o = toVector3(origin, "origin");
  Frame frame;
  frame.T_world_sensor = Eigen::Translation3d(o);
  if (!colours.is_none()) frame.cloud.colours = toColours(colours, points.size(), "colors");
  frame.source = "add_points";
  const ObjectLock lock(&integrator);
  py::gil_scoped_release release;
  frame.cloud.points.reserve(points.size());
  for (const Eigen::Vector3d& p : points) frame.cloud.points.push_back((p - o).cast<float>());
  frame.cloud.width = static_cast<uint32_t>(points.size());
  integrator.add(frame);
}

std::unique_ptr<IncrementalIntegrator> makeIntegrator(double resolution_m, double max_range_m, bool fast,
                                                      bool compress_free, bool carve_beyond_range,
                                                      const py::object& carve_level, double depth_edges) {
  IntegratorSettings settings;
  settings.depth_edge_ratio = depth_edges;
  settings.carve_level = toCarveLevel(carve_level);
  settings.max_range_m = max_range_m;
  settings.carve_beyond_range = carve_beyond_range;
  settings.fast = fast;
  settings.threads = 1;
  settings.compress_free = compress_free;
  return std::make_unique<IncrementalIntegrator>(resolution_m, settings);
}

}  // namespace

void bindIntegrate(py::module_& m) {
  m.def("read_depth_png", &readDepthPng, py::arg("path"), "A 16-bit PNG (a depth image) as an (H, W) uint16 array.");
  m.def("read_color_png", &readColourPng, py::arg("path"), "A PNG as an (H, W, 3) uint8 RGB array.");
  m.def(
      "formats",
      [] {
        py::list out;
        for (const DatasetReader& r : registerReaders()) {
          py::dict d;
          d["name"] = r.name;
          d["aliases"] = r.aliases;
          d["description"] = r.description;
          out.append(d);
        }
        return out;
      },
      "The recording formats this build reads, in the order detection tries them: a list of dicts "
      "with 'name' (what `format=` takes), 'aliases' and 'description' (as `chronomap integrate "
      "--list-formats`).");
  m.def("integrate_dataset", &integrateDatasetPy, py::arg("path"), py::arg("resolution_m") = 0.05,
        py::arg("fast") = false, py::arg("max_range_m") = 3.0, py::arg("threads") = 0, py::arg("format") = "auto",
        py::arg("depth_scale") = py::none(), py::arg("progress") = py::none(), py::arg("carve_beyond_range") = false,
        py::arg("carve_level") = "auto", py::arg("up") = py::none(), py::arg("depth_edges") = 0.0,
        "Integrates the recording at `path` (any format formats() lists, as "
        "`chronomap integrate` reads it) into a SessionMap. `progress`, if given, is called as "
        "progress(label, done, total) after each frame (on another thread, with the GIL). The GIL is released while "
        "it runs; Ctrl-C stops it at the next frame with KeyboardInterrupt. "
        "carve_beyond_range=True carves free space along the rays of points beyond max_range_m, up to the "
        "range (`--carve-beyond-range`). carve_level (fast mode): free space far from the surfaces in cubes of "
        "2**L voxels per axis; 'auto' is 2 at 0.025 m and finer, 0 (off) above (`--carve-level`). "
        "up: which axis of the recording's world frame is up ('+x' .. '-z', or 'auto': estimated from the floor; "
        "None: +z), the frames turned so that it becomes +z (`--up`, docs/frames.md). depth_edges: drop a depth "
        "image's points whose range differs from a neighbouring pixel's by more than this share of their own (flying "
        "pixels at object edges; 0: off, `--depth-edges`, docs/integration.md).");

  py::class_<IncrementalIntegrator>(m, "Integrator",
                                    "Integrates frames one at a time; finish() gives the map integrate_dataset gives "
                                    "for the same frames and settings.")
      .def(py::init(&makeIntegrator), py::arg("resolution_m") = 0.05, py::arg("max_range_m") = 3.0,
           py::arg("fast") = false, py::arg("compress_free") = true, py::arg("carve_beyond_range") = false,
           py::arg("carve_level") = "auto", py::arg("depth_edges") = 0.0)
      .def("add_frame", &addFrame, py::arg("depth"), py::arg("intrinsics"), py::arg("T_world_camera"),
           py::arg("rgb") = py::none(), py::arg("depth_scale") = 1000.0,
           "Adds a depth image: (H, W) uint16 with depth_scale units per metre, or float32 metres (0 = no "
           "measurement); intrinsics (fx, fy, cx, cy) or a 3x3 K (focal lengths positive, all finite, else "
           "UsageError); T_world_camera a 4x4 camera-to-world "
           "matrix; rgb an optional (H, W, 3) uint8 image.")
      .def("add_points", &addPoints, py::arg("points_world"), py::arg("origin"), py::arg("colors") = py::none(),
           "Adds (N, 3) points in the world frame seen from the sensor at `origin` (3,), with optional "
           "(N, 3) uint8 colours.")
      .def_property_readonly(
          "map",
          [](const IncrementalIntegrator& i) {
            const ObjectLock lock(&i);
            py::gil_scoped_release release;
            return i.map();
          },
          "A copy of the map so far (free space not yet compressed).")
      .def_property_readonly(
          "frames",
          [](const IncrementalIntegrator& i) {
            const ObjectLock lock(&i);
            return i.stats().frames;
          },
          "Frames added so far.")
      .def_property_readonly(
          "points",
          [](const IncrementalIntegrator& i) {
            const ObjectLock lock(&i);
            return i.stats().points;
          },
          "Points cast as rays so far.")
      .def(
          "finish",
          [](IncrementalIntegrator& i) {
            const ObjectLock lock(&i);
            py::gil_scoped_release release;
            return i.finish();
          },
          "The map, compressed as integrate_dataset leaves it; the integrator starts again empty.");
}

}  // namespace chronomap::python
