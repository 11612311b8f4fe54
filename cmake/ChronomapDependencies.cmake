# All dependencies come from Debian packages; scripts/install-deps.sh installs them.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(TBB REQUIRED)
find_package(CLI11 REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(PNG REQUIRED)
find_package(JPEG REQUIRED)
find_package(ZLIB REQUIRED)
find_package(BZip2 REQUIRED)
find_package(octomap REQUIRED)
find_package(Threads REQUIRED)

find_path(ZSTD_INCLUDE_DIR zstd.h REQUIRED)
find_library(ZSTD_LIBRARY zstd REQUIRED)
add_library(chronomap_zstd INTERFACE)
target_include_directories(chronomap_zstd SYSTEM INTERFACE ${ZSTD_INCLUDE_DIR})
target_link_libraries(chronomap_zstd INTERFACE ${ZSTD_LIBRARY})

find_path(LZF_INCLUDE_DIR lzf.h PATH_SUFFIXES liblzf REQUIRED)
find_library(LZF_LIBRARY lzf REQUIRED)
add_library(chronomap_lzf INTERFACE)
target_include_directories(chronomap_lzf SYSTEM INTERFACE ${LZF_INCLUDE_DIR})
target_link_libraries(chronomap_lzf INTERFACE ${LZF_LIBRARY})

# ROS 2 bags: lz4 frames inside MCAP chunks, and SQLite for the .db3 storage.
find_path(LZ4_INCLUDE_DIR lz4frame.h REQUIRED)
find_library(LZ4_LIBRARY lz4 REQUIRED)
add_library(chronomap_lz4 INTERFACE)
target_include_directories(chronomap_lz4 SYSTEM INTERFACE ${LZ4_INCLUDE_DIR})
target_link_libraries(chronomap_lz4 INTERFACE ${LZ4_LIBRARY})
find_package(SQLite3 REQUIRED)

add_library(chronomap_octomap INTERFACE)
target_include_directories(chronomap_octomap SYSTEM INTERFACE ${OCTOMAP_INCLUDE_DIRS})
target_link_libraries(chronomap_octomap INTERFACE ${OCTOMAP_LIBRARIES})

# cpp-httplib (the viewer's server): Debian builds it as a library with TLS and compression,
# and its header must be compiled with the same definitions, which pkg-config gives.
find_package(PkgConfig REQUIRED)
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)

# ROS 1 bags: Debian's librosbag (rosbag_storage) and the generated headers of the message
# packages. Only src/ingest/ros/rosbag1.cpp includes them; the include folders are SYSTEM so that the
# ROS headers' own warnings do not fail the build.
option(CHRONOMAP_ROS "Build the ROS bag readers (chronomap_ingest_ros: ROS 2 MCAP and .db3, and ROS 1 through librosbag)" ON)
option(CHRONOMAP_ROSBAG "Read ROS 1 bags through librosbag (scripts/install-deps.sh installs it)" ON)
if(CHRONOMAP_ROS AND CHRONOMAP_ROSBAG)
  find_path(ROSBAG_INCLUDE_DIR rosbag/bag.h)
  find_path(ROS_SENSOR_MSGS_INCLUDE_DIR sensor_msgs/Image.h)
  find_path(ROS_TF2_MSGS_INCLUDE_DIR tf2_msgs/TFMessage.h)
  find_path(ROS_NAV_MSGS_INCLUDE_DIR nav_msgs/Odometry.h)
  find_path(PLUGINLIB_INCLUDE_DIR pluginlib/class_loader.hpp PATH_SUFFIXES pluginlib)
  find_path(CLASS_LOADER_INCLUDE_DIR class_loader/class_loader.hpp PATH_SUFFIXES class_loader)
  find_path(RCUTILS_INCLUDE_DIR rcutils/types.h PATH_SUFFIXES rcutils)
  find_path(RCPPUTILS_INCLUDE_DIR rcpputils/shared_library.hpp PATH_SUFFIXES rcpputils)
  find_path(AMENT_INDEX_CPP_INCLUDE_DIR ament_index_cpp/get_resource.hpp PATH_SUFFIXES ament_index_cpp)
  set(_chronomap_ros_libraries)
  foreach(lib rosbag_storage roslz4 rostime cpp_common roscpp_serialization console_bridge boost_filesystem)
    find_library(CHRONOMAP_ROS_${lib}_LIBRARY ${lib})
    list(APPEND _chronomap_ros_libraries CHRONOMAP_ROS_${lib}_LIBRARY)
  endforeach()
  foreach(var ROSBAG_INCLUDE_DIR ROS_SENSOR_MSGS_INCLUDE_DIR ROS_TF2_MSGS_INCLUDE_DIR ROS_NAV_MSGS_INCLUDE_DIR
              PLUGINLIB_INCLUDE_DIR CLASS_LOADER_INCLUDE_DIR RCUTILS_INCLUDE_DIR RCPPUTILS_INCLUDE_DIR
              AMENT_INDEX_CPP_INCLUDE_DIR ${_chronomap_ros_libraries})
    if(NOT ${var})
      message(FATAL_ERROR "ROS 1 bag support needs ${var}: run scripts/install-deps.sh "
                          "(librosbag-dev, libsensor-msgs-dev, libnav-msgs-dev, libtf2-msgs-dev), "
                          "or configure with -DCHRONOMAP_ROSBAG=OFF")
    endif()
  endforeach()
  add_library(chronomap_rosbag INTERFACE)
  target_include_directories(chronomap_rosbag SYSTEM INTERFACE ${ROSBAG_INCLUDE_DIR} ${ROS_SENSOR_MSGS_INCLUDE_DIR}
    ${ROS_TF2_MSGS_INCLUDE_DIR} ${ROS_NAV_MSGS_INCLUDE_DIR} ${PLUGINLIB_INCLUDE_DIR} ${CLASS_LOADER_INCLUDE_DIR}
    ${RCUTILS_INCLUDE_DIR} ${RCPPUTILS_INCLUDE_DIR} ${AMENT_INDEX_CPP_INCLUDE_DIR})
  foreach(var ${_chronomap_ros_libraries})
    target_link_libraries(chronomap_rosbag INTERFACE ${${var}})
  endforeach()
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
