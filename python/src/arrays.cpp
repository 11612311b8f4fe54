#include <string>

#include "bindings.h"

namespace chronomap::python {

namespace {

[[noreturn]] void wrongDtype(const char* name, const py::array& a, const char* wanted) {
  std::string msg(name);
  msg.append(": expected ").append(wanted).append(", got dtype ").append(py::str(a.dtype()).cast<std::string>());
  throw py::type_error(msg);
}

[[noreturn]] void wrongShape(const char* name, const py::array& a, const char* wanted) {
  std::string msg(name);
  msg.append(": expected shape ").append(wanted).append(", got ");
  msg.append(py::str(py::tuple(a.attr("shape"))).cast<std::string>());
  throw py::value_error(msg);
}

/// `a` as a C-contiguous float64 array (a copy when it is another dtype or layout).
py::array_t<double, py::array::c_style> realArray(const py::handle& h, const char* name) {
  const py::array a = py::array::ensure(h);
  if (!a) throw py::type_error(std::string(name) + ": expected an array of numbers");
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') wrongDtype(name, a, "real numbers");
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
}

}  // namespace

std::vector<Eigen::Vector3d> toPoints(const py::handle& h, const char* name) {
  const auto a = realArray(h, name);
  if (a.ndim() != 2 || a.shape(1) != 3) wrongShape(name, a, "(N, 3)");
  std::vector<Eigen::Vector3d> out(static_cast<size_t>(a.shape(0)));
  const double* p = a.data();
  for (size_t i = 0; i < out.size(); ++i) out[i] = Eigen::Vector3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
  return out;
}

Eigen::Vector3d toVector3(const py::handle& h, const char* name) {
  const auto a = realArray(h, name);
  if (a.size() != 3 || a.ndim() != 1) wrongShape(name, a, "(3,)");
  return Eigen::Vector3d(a.data()[0], a.data()[1], a.data()[2]);
}

Eigen::Matrix4d toMatrix4(const py::handle& h, const char* name) {
  const auto a = realArray(h, name);
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) wrongShape(name, a, "(4, 4)");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = a.data()[4 * r + c];
  }
  return m;
}

ImageRgb toRgbImage(const py::handle& h, const char* name) {
  const py::array any = py::array::ensure(h);
  if (!any) throw py::type_error(std::string(name) + ": expected an array");
  if (!any.dtype().is(py::dtype::of<uint8_t>())) wrongDtype(name, any, "uint8");
  const auto a = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(any);
  if (a.ndim() != 3 || a.shape(2) != 3) wrongShape(name, a, "(H, W, 3)");
  ImageRgb img;
  img.height = static_cast<uint32_t>(a.shape(0));
  img.width = static_cast<uint32_t>(a.shape(1));
  img.pixels.resize(size_t{img.width} * img.height);
  const uint8_t* p = a.data();
  for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = Rgb{p[3 * i], p[3 * i + 1], p[3 * i + 2]};
  return img;
}

std::vector<Rgb> toColours(const py::handle& h, size_t n, const char* name) {
  const py::array any = py::array::ensure(h);
  if (!any) throw py::type_error(std::string(name) + ": expected an array");
  if (!any.dtype().is(py::dtype::of<uint8_t>())) wrongDtype(name, any, "uint8");
  const auto a = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(any);
  if (a.ndim() != 2 || a.shape(1) != 3 || static_cast<size_t>(a.shape(0)) != n) {
    wrongShape(name, a, "(N, 3) with N the number of points");
  }
  std::vector<Rgb> out(n);
  const uint8_t* p = a.data();
  for (size_t i = 0; i < n; ++i) out[i] = Rgb{p[3 * i], p[3 * i + 1], p[3 * i + 2]};
  return out;
}

py::array_t<double> pointsArray(std::vector<Eigen::Vector3d> points) {
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double));
  auto* owned = new std::vector<Eigen::Vector3d>(std::move(points));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<Eigen::Vector3d>*>(p); });
  const auto n = static_cast<py::ssize_t>(owned->size());
  return py::array_t<double>({n, py::ssize_t{3}}, owned->empty() ? nullptr : owned->front().data(), free);
}

py::array_t<uint8_t> coloursArray(std::vector<Rgb> colours) {
  static_assert(sizeof(Rgb) == 3);
  auto* owned = new std::vector<Rgb>(std::move(colours));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<Rgb>*>(p); });
  const auto n = static_cast<py::ssize_t>(owned->size());
  return py::array_t<uint8_t>({n, py::ssize_t{3}}, owned->empty() ? nullptr : &owned->front().r, free);
}

py::array_t<double> vector3Array(const Eigen::Vector3d& v) {
  py::array_t<double> out(3);
  for (int i = 0; i < 3; ++i) out.mutable_data()[i] = v[i];
  return out;
}

}  // namespace chronomap::python
