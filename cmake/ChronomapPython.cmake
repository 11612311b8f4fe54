# The Python package (python/): built when pybind11, Python's headers and numpy are found, for
# Debian's /usr/bin/python3 unless CHRONOMAP_PYTHON names another interpreter (the first
# python3 on PATH may be a pyenv shim that Debian's python3-* packages do not serve).
set(CHRONOMAP_PYTHON "/usr/bin/python3" CACHE FILEPATH "Python interpreter the bindings are built and tested for")
set(Python_EXECUTABLE "${CHRONOMAP_PYTHON}")
find_package(Python COMPONENTS Interpreter Development.Module NumPy)
if(Python_FOUND)
  find_package(pybind11 CONFIG QUIET)
endif()
if(CHRONOMAP_SANITIZE OR CHRONOMAP_TSAN OR CHRONOMAP_FUZZ)
  # An instrumented module does not load into an uninstrumented interpreter.
  set(chronomap_python_default OFF)
elseif(Python_FOUND AND pybind11_FOUND)
  set(chronomap_python_default ON)
else()
  message(STATUS "chronomap: Python bindings off (needs pybind11-dev, python3-dev and python3-numpy for "
                 "${CHRONOMAP_PYTHON}; scripts/install-deps.sh installs them)")
  set(chronomap_python_default OFF)
endif()
option(CHRONOMAP_BUILD_PYTHON "Build the Python package (python/)" ${chronomap_python_default})
if(CHRONOMAP_BUILD_PYTHON)
  if(NOT (Python_FOUND AND pybind11_FOUND))
    message(FATAL_ERROR "CHRONOMAP_BUILD_PYTHON is ON but pybind11 or Python ${CHRONOMAP_PYTHON} was not found")
  endif()
  # The module is a shared object: the static module libraries it links must be position
  # independent.
  set(CMAKE_POSITION_INDEPENDENT_CODE ON)
endif()
