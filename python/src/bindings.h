#pragma once
// The pieces of the _chronomap module and the array conversions they share. The bindings wrap
// library calls (pipeline/ and the modules below) and add no logic of their own.

#include <cstdint>
#include <memory>
#include <string>
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

namespace chronomap::python {

namespace py = pybind11;

void bindErrors(py::module_& m);
void bindMaps(py::module_& m);
void bindIntegrate(py::module_& m);
void bindTemporal(py::module_& m);
void bindAnalysis(py::module_& m);
void bindPipeline(py::module_& m);
void bindRhythm(py::module_& m);

/// Forwards pipeline progress to a Python callable(label, done, total), taking the GIL for the
/// call. An exception it raises is kept and raised again once the library call has returned
/// (rethrow()); later reports are then dropped.
struct ProgressForwarder {
  py::object callback;
  std::shared_ptr<py::error_already_set> raised;

  Progress progress();
  void rethrow() const;
};

/// A time as epoch seconds: a real number, or a datetime.datetime (naive ones are taken as
/// UTC). @throw py::type_error for anything else, naming `name`.
double toSeconds(const py::handle& time, const char* name);
/// Epoch seconds as an aware datetime.datetime in UTC.
py::object toDatetime(double time_s);

/// The settings of diff() and TemporalMap.diff(). @throw UsageError for an unknown mode.
DiffSettings diffSettings(const std::string& mode, double alpha, int neighbourhood_voxels, double min_shift_voxels,
                          int kept_surface_radius_voxels, double kept_surface_share, int dark_surface_radius_voxels,
                          double dark_surface_brightness, double dark_surface_contrast, double dark_surface_share);

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
