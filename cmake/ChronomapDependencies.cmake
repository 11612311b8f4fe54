# All dependencies come from Debian packages; scripts/install-deps.sh installs them.
# The libraries' dependencies are found by cmake/chronomapFindDependencies.cmake, which the
# installed CMake package includes too; CLI11 is the command line's alone.
option(CHRONOMAP_ROS "Build the ROS bag readers (chronomap_ingest_ros: ROS 2 MCAP and .db3, and ROS 1 through librosbag)" ON)
option(CHRONOMAP_ROSBAG "Read ROS 1 bags through librosbag (scripts/install-deps.sh installs it)" ON)
set(CHRONOMAP_DEPS_ROS2 ${CHRONOMAP_ROS})
if(CHRONOMAP_ROS AND CHRONOMAP_ROSBAG)
  set(CHRONOMAP_DEPS_ROS1 ON)
else()
  set(CHRONOMAP_DEPS_ROS1 OFF)
endif()
set(CHRONOMAP_DEPS_MPI OFF)  # found below, where it is optional
include(chronomapFindDependencies)
find_package(CLI11 REQUIRED)

# The project's names for the imported libraries (an alias exports as the target it names).
add_library(chronomap_zstd ALIAS chronomap_dep::zstd)
add_library(chronomap_lzf ALIAS chronomap_dep::lzf)
add_library(chronomap_octomap ALIAS chronomap_dep::octomap)
if(CHRONOMAP_DEPS_ROS2)
  add_library(chronomap_lz4 ALIAS chronomap_dep::lz4)
endif()
if(CHRONOMAP_DEPS_ROS1)
  add_library(chronomap_rosbag ALIAS chronomap_dep::rosbag)
endif()

# MPI (Open MPI from Debian, scripts/install-deps.sh): `mpirun -np N chronomap build` spreads the
# integration over processes (pipeline/distributed.h, the only file that calls MPI). Optional:
# AUTO uses it when found; without it the same command runs on one process. Under CI=true it
# must be found, so that its tests run rather than vanish.
set(CHRONOMAP_MPI AUTO CACHE STRING "Build with MPI: AUTO (when found), ON (required) or OFF")
set_property(CACHE CHRONOMAP_MPI PROPERTY STRINGS AUTO ON OFF)
set(CHRONOMAP_HAVE_MPI OFF)
if(NOT CHRONOMAP_MPI STREQUAL "OFF")
  find_package(MPI COMPONENTS CXX)
  if(MPI_CXX_FOUND AND MPIEXEC_EXECUTABLE)
    set(CHRONOMAP_HAVE_MPI ON)
  elseif(CHRONOMAP_MPI STREQUAL "ON" OR "$ENV{CI}" STREQUAL "true")
    message(FATAL_ERROR "MPI (C++ and mpirun) not found: run scripts/install-deps.sh (libopenmpi-dev, openmpi-bin), "
                        "or configure with -DCHRONOMAP_MPI=OFF")
  endif()
endif()
message(STATUS "chronomap: MPI ${CHRONOMAP_HAVE_MPI}")
