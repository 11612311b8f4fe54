# The packages and libraries chronomap's libraries link, as targets. Both the project's build
# (cmake/ChronomapDependencies.cmake) and the installed CMake package (chronomapConfig.cmake, for
# the static libraries, whose private dependencies their users link) include this file, so that
# an installed chronomap finds what it was built with, by the same means.
#
# In: CHRONOMAP_DEPS_ROS2 (ROS 2 bags: lz4, SQLite), CHRONOMAP_DEPS_ROS1 (librosbag and the
# message headers), CHRONOMAP_DEPS_MPI (MPI::MPI_CXX), CHRONOMAP_DEPS_FOR_PACKAGE (ON inside
# chronomapConfig.cmake: a missing dependency makes find_package(chronomap) fail with its name
# instead of stopping the configuration).
# Out: Eigen3::Eigen, TBB::tbb, nlohmann_json::nlohmann_json, PNG::PNG, JPEG::JPEG, ZLIB::ZLIB,
# BZip2::BZip2, PkgConfig::HTTPLIB, SQLite::SQLite3, MPI::MPI_CXX, and imported targets for the
# libraries without a CMake package: chronomap_dep::zstd, ::lzf, ::lz4, ::octomap, ::rosbag.
include(CMakeFindDependencyMacro)

# find_package in the project (REQUIRED), find_dependency in the installed package (which
# returns from this file with chronomap_FOUND false and the package named).
macro(_chronomap_find_package)
  if(CHRONOMAP_DEPS_FOR_PACKAGE)
    find_dependency(${ARGN})
  else()
    find_package(${ARGN} REQUIRED)
  endif()
endmacro()

# chronomap_dep::NAME as an interface target of `includes` and `libraries` (global in the
# project, local to the directory that finds the installed package).
function(_chronomap_dependency_target name includes libraries)
  if(CHRONOMAP_DEPS_FOR_PACKAGE)
    add_library(chronomap_dep::${name} INTERFACE IMPORTED)
  else()
    add_library(chronomap_dep::${name} INTERFACE IMPORTED GLOBAL)
  endif()
  set_target_properties(chronomap_dep::${name} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${includes}"
                                                          INTERFACE_LINK_LIBRARIES "${libraries}")
endfunction()

# A library without a CMake package: chronomap_dep::NAME from its header and library files.
# Returns false in OUT_FOUND when either is missing.
function(_chronomap_import_library name header library out_found)
  set(${out_found} TRUE PARENT_SCOPE)
  if(TARGET chronomap_dep::${name})
    return()
  endif()
  cmake_parse_arguments(PARSE_ARGV 4 arg "" "" "PATH_SUFFIXES")
  find_path(CHRONOMAP_DEP_${name}_INCLUDE_DIR ${header} PATH_SUFFIXES ${arg_PATH_SUFFIXES})
  find_library(CHRONOMAP_DEP_${name}_LIBRARY ${library})
  if(NOT CHRONOMAP_DEP_${name}_INCLUDE_DIR OR NOT CHRONOMAP_DEP_${name}_LIBRARY)
    set(${out_found} FALSE PARENT_SCOPE)
    return()
  endif()
  _chronomap_dependency_target(${name} "${CHRONOMAP_DEP_${name}_INCLUDE_DIR}" "${CHRONOMAP_DEP_${name}_LIBRARY}")
endfunction()

# Stops: with a message in the project, as a failed find_package(chronomap) in the package.
macro(_chronomap_dependency_missing what install)
  if(CHRONOMAP_DEPS_FOR_PACKAGE)
    set(chronomap_FOUND FALSE)
    set(chronomap_NOT_FOUND_MESSAGE "chronomap needs ${what} (Debian: ${install})")
    return()
  endif()
  message(FATAL_ERROR "chronomap needs ${what}: run scripts/install-deps.sh (${install})")
endmacro()

_chronomap_find_package(Eigen3 3.3 NO_MODULE)
_chronomap_find_package(TBB)
_chronomap_find_package(nlohmann_json 3)
_chronomap_find_package(PNG)
_chronomap_find_package(JPEG)
_chronomap_find_package(ZLIB)
_chronomap_find_package(BZip2)
_chronomap_find_package(Threads)
_chronomap_find_package(PkgConfig)
# cpp-httplib (the viewer's server): Debian builds it as a library with TLS and compression,
# and its header must be compiled with the same definitions, which pkg-config gives.
if(NOT TARGET PkgConfig::HTTPLIB)
  pkg_check_modules(HTTPLIB QUIET IMPORTED_TARGET cpp-httplib)
  if(NOT HTTPLIB_FOUND)
    _chronomap_dependency_missing("cpp-httplib" "libcpp-httplib-dev")
  endif()
endif()

_chronomap_import_library(zstd zstd.h zstd found)
if(NOT found)
  _chronomap_dependency_missing("zstd" "libzstd-dev")
endif()
_chronomap_import_library(lzf lzf.h lzf found PATH_SUFFIXES liblzf)
if(NOT found)
  _chronomap_dependency_missing("liblzf" "liblzf-dev")
endif()

if(NOT TARGET chronomap_dep::octomap)
  _chronomap_find_package(octomap)
  _chronomap_dependency_target(octomap "${OCTOMAP_INCLUDE_DIRS}" "${OCTOMAP_LIBRARIES}")
endif()

# ROS 2 bags: lz4 frames inside MCAP chunks, and SQLite for the .db3 storage.
if(CHRONOMAP_DEPS_ROS2)
  _chronomap_import_library(lz4 lz4frame.h lz4 found)
  if(NOT found)
    _chronomap_dependency_missing("lz4" "liblz4-dev")
  endif()
  _chronomap_find_package(SQLite3)
endif()

# ROS 1 bags: Debian's librosbag (rosbag_storage) and the generated headers of the message
# packages. Only src/ingest/ros/rosbag1.cpp includes them.
if(CHRONOMAP_DEPS_ROS1 AND NOT TARGET chronomap_dep::rosbag)
  set(_chronomap_ros_includes)
  foreach(entry rosbag/bag.h sensor_msgs/Image.h tf2_msgs/TFMessage.h nav_msgs/Odometry.h
                pluginlib/class_loader.hpp@pluginlib class_loader/class_loader.hpp@class_loader
                rcutils/types.h@rcutils rcpputils/shared_library.hpp@rcpputils
                ament_index_cpp/get_resource.hpp@ament_index_cpp)
    string(REPLACE "@" ";" parts "${entry}")
    list(GET parts 0 header)
    list(LENGTH parts n)
    set(suffix)
    if(n GREATER 1)
      list(GET parts 1 suffix)
    endif()
    string(MAKE_C_IDENTIFIER "CHRONOMAP_ROS_${header}" var)
    find_path(${var} ${header} PATH_SUFFIXES ${suffix})
    if(NOT ${var})
      _chronomap_dependency_missing("${header} for ROS 1 bags"
        "librosbag-dev, libsensor-msgs-dev, libnav-msgs-dev, libtf2-msgs-dev; or configure with -DCHRONOMAP_ROSBAG=OFF")
    endif()
    list(APPEND _chronomap_ros_includes ${${var}})
  endforeach()
  set(_chronomap_ros_libraries)
  foreach(lib rosbag_storage roslz4 rostime cpp_common roscpp_serialization console_bridge boost_filesystem)
    find_library(CHRONOMAP_ROS_${lib}_LIBRARY ${lib})
    if(NOT CHRONOMAP_ROS_${lib}_LIBRARY)
      _chronomap_dependency_missing("lib${lib} for ROS 1 bags" "librosbag-dev; or configure with -DCHRONOMAP_ROSBAG=OFF")
    endif()
    list(APPEND _chronomap_ros_libraries ${CHRONOMAP_ROS_${lib}_LIBRARY})
  endforeach()
  list(REMOVE_DUPLICATES _chronomap_ros_includes)
  _chronomap_dependency_target(rosbag "${_chronomap_ros_includes}" "${_chronomap_ros_libraries}")
endif()

if(CHRONOMAP_DEPS_MPI)
  _chronomap_find_package(MPI COMPONENTS CXX)
endif()
