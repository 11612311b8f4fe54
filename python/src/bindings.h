#pragma once
// The pieces of the _chronomap module and the array conversions they share. The bindings wrap
// library calls (pipeline/ and the modules below) and add no logic of their own.

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "chronomap/analysis/diff.h"
#include "chronomap/core/counters.h"
#include "chronomap/core/image.h"
#include "chronomap/pipeline/progress.h"
#include "chronomap/pipeline/session.h"

namespace chronomap::python {

namespace py = pybind11;

void bindErrors(py::module_& m);
void bindMaps(py::module_& m);
void bindIntegrate(py::module_& m);
void bindTemporal(py::module_& m);
void bindAnalysis(py::module_& m);
void bindPipeline(py::module_& m);
void bindRhythm(py::module_& m);

/// Serialises the calls on one bound object whose state changes (a TemporalMap, an Integrator):
/// every method of those classes, and every function that reads one, holds the object's lock
/// from its first line to its return, including while the GIL is released. A second thread
/// waits (without the GIL) until the first is done, so threads sharing an object get what
/// calling one after another gives. Construct with the GIL held. Nothing holding a lock calls
/// back into Python code that could ask for the same lock.
class ObjectLock {
 public:
  explicit ObjectLock(const void* object);
  /// Both objects' locks, taken in address order (one lock when they are the same object).
  ObjectLock(const void* a, const void* b);
  ~ObjectLock();
  ObjectLock(const ObjectLock&) = delete;
  ObjectLock& operator=(const ObjectLock&) = delete;

  struct Slot;

 private:
  static Slot* acquire(const void* object);
  static void release(const void* object, Slot* slot);
  std::array<std::pair<const void*, Slot*>, 2> held_{};
};

/// A long library call that Ctrl-C stops. The call runs on a worker thread while the calling
/// thread waits without the GIL and, every 20 ms, runs Python's signal handlers
/// (PyErr_CheckSignals: only the main thread runs them, so a call blocked in C++ on the main
/// thread would never see Ctrl-C). When a handler raises (KeyboardInterrupt), the call is
/// stopped at its next progress report (the library unwinds as on an error: nothing is
/// written), waited for, and the handler's exception is raised. progress() also forwards each
/// report to the Python `callback(label, done, total)` with the GIL; an exception that raises
/// stops the call the same way and is raised.
class LongCall {
 public:
  explicit LongCall(py::object callback = py::none());
  /// For the library call: every step and report first checks whether to stop.
  Progress progress();
  /// Runs `work` (which must not touch Python objects) as described. Call with the GIL held.
  template <class Fn>
  auto run(Fn&& work) -> decltype(work()) {
    std::optional<decltype(work())> result;
    runErased([&] { result.emplace(work()); });
    return std::move(*result);
  }

 private:
  void runErased(const std::function<void()>& work);
  py::object callback_;
  bool has_callback_ = false;
  std::atomic<bool> stop_{false};
  std::shared_ptr<py::error_already_set> raised_;  // by the callback
};

/// A time as epoch seconds: a real number, an ISO-8601 string as the command line takes it
/// (parseTime, core/time.h: "2012-03-01T10:00:00Z"; no zone means UTC), or a datetime.datetime
/// (naive ones are taken as UTC), checked by checkTime as the command line checks its times.
/// @throw py::type_error for anything else, naming `name`; UsageError (a ValueError) for NaN,
/// a time outside the years 1 to 9999 or text parseTime refuses, naming `name` and the value.
double toSeconds(const py::handle& time, const char* name);
/// Epoch seconds as an aware datetime.datetime in UTC.
py::object toDatetime(double time_s);

/// The `up` argument of integrate_dataset() and build() (`--up`, docs/frames.md): None (+z; build:
/// the map's own), an axis ("+x" .. "-z") or "auto". @throw UsageError (a ValueError) naming `up`.
UpSettings toUpSettings(const py::object& up);

/// The settings of diff() and TemporalMap.diff(). @throw UsageError for an unknown mode.
DiffSettings diffSettings(const std::string& mode, double alpha, int neighbourhood_voxels, double min_shift_voxels,
                          int kept_surface_radius_voxels, double kept_surface_share, int dark_surface_radius_voxels,
                          double dark_surface_brightness, double dark_surface_contrast, double dark_surface_share,
                          double shift_plane_ratio);

/// An (N, 3) array of real numbers (any layout) as points. @throw py::type_error for another
/// dtype, py::value_error for another shape; both name `name`.
std::vector<Eigen::Vector3d> toPoints(const py::handle& a, const char* name);
/// A 3-vector. @throw as toPoints.
Eigen::Vector3d toVector3(const py::handle& a, const char* name);
/// A 4x4 matrix. @throw as toPoints.
Eigen::Matrix4d toMatrix4(const py::handle& a, const char* name);
/// An H x W x 3 uint8 image. @throw as toPoints.
ImageRgb toRgbImage(const py::handle& a, const char* name);
/// (N, 3) uint8 colours for `n` points. @throw as toPoints.
std::vector<Rgb> toColours(const py::handle& a, size_t n, const char* name);

/// Arrays that own the vectors they are made from (moved, not copied).
py::array_t<double> pointsArray(std::vector<Eigen::Vector3d> points);
py::array_t<uint8_t> coloursArray(std::vector<Rgb> colours);
template <class T>
py::array_t<T> vectorArray(std::vector<T> values) {
  auto* owned = new std::vector<T>(std::move(values));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>({static_cast<py::ssize_t>(owned->size())}, owned->data(), free);
}
/// A 3-vector as a (3,) float64 array.
py::array_t<double> vector3Array(const Eigen::Vector3d& v);

}  // namespace chronomap::python
