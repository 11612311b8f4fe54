// The extension module _chronomap; the package chronomap re-exports it (python/chronomap).

#include "bindings.h"
#include "chronomap/core/error.h"

namespace chronomap::python {

void bindErrors(py::module_& m) {
  // Registered base first: pybind11 tries the translators of the most recent registrations
  // first, so each C++ type meets its own Python type before its base's.
  const auto error = py::register_exception<Error>(m, "Error", PyExc_RuntimeError);
  const auto data = py::register_exception<DataError>(m, "DataError", error);
  py::register_exception<FormatError>(m, "FormatError", data);
  py::register_exception<IoError>(m, "IoError", py::make_tuple(error, py::handle(PyExc_OSError)));
  py::register_exception<UsageError>(m, "UsageError", py::make_tuple(error, py::handle(PyExc_ValueError)));
}

}  // namespace chronomap::python

PYBIND11_MODULE(_chronomap, m) {
  namespace python = chronomap::python;
  m.doc() = "chronomap: 4D (temporal octree) maps of RGB-D recordings, with numpy arrays in and out.";
  python::bindErrors(m);
  python::bindMaps(m);
  python::bindIntegrate(m);
  python::bindTemporal(m);
  python::bindAnalysis(m);
  python::bindPipeline(m);
  python::bindRhythm(m);
}
