# What `cmake --install` puts into the prefix, in three components (docs/install.md):
#   runtime:     bin/chronomap, the shared libraries, the man pages
#   development: include/chronomap, the static libraries, the CMake package, chronomap.pc
#   python:      the Python package (python/CMakeLists.txt, into CHRONOMAP_PYTHON_INSTALL_DIR)
# and the Debian package CPack makes of all three (scripts/package-deb.sh).
include(CMakePackageConfigHelpers)
set(CHRONOMAP_CMAKE_INSTALL_DIR "${CMAKE_INSTALL_LIBDIR}/cmake/chronomap")
get_property(chronomap_modules GLOBAL PROPERTY CHRONOMAP_MODULES)

# The libraries: static ones as chronomap-static-targets.cmake, shared ones (when built) as
# chronomap-shared-targets.cmake, each set under the same names (chronomap::core, ...).
set(chronomap_static_targets chronomap)
set(chronomap_shared_targets)
foreach(name ${chronomap_modules})
  list(APPEND chronomap_static_targets chronomap_${name})
  list(APPEND chronomap_shared_targets chronomap_${name}_shared)
endforeach()
install(TARGETS ${chronomap_static_targets} EXPORT chronomapStaticTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development)
install(EXPORT chronomapStaticTargets NAMESPACE chronomap:: FILE chronomap-static-targets.cmake
        DESTINATION ${CHRONOMAP_CMAKE_INSTALL_DIR} COMPONENT development)
if(CHRONOMAP_SHARED_LIBS)
  install(TARGETS ${chronomap_shared_targets} chronomap_shared EXPORT chronomapSharedTargets
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT runtime NAMELINK_COMPONENT development)
  install(EXPORT chronomapSharedTargets NAMESPACE chronomap:: FILE chronomap-shared-targets.cmake
          DESTINATION ${CHRONOMAP_CMAKE_INSTALL_DIR} COMPONENT development)
endif()

# The public headers, and the generated one (version and optional parts).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/chronomap DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        COMPONENT development)
install(FILES ${CHRONOMAP_GENERATED_INCLUDE_DIR}/chronomap/version.h
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/chronomap COMPONENT development)

# The CMake package.
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/chronomapConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/package/chronomapConfig.cmake
                              INSTALL_DESTINATION ${CHRONOMAP_CMAKE_INSTALL_DIR})
# 0.x: a new minor version may change the interface.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/package/chronomapConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/package/chronomapConfig.cmake
              ${PROJECT_BINARY_DIR}/package/chronomapConfigVersion.cmake
              ${PROJECT_SOURCE_DIR}/cmake/chronomapFindDependencies.cmake
        DESTINATION ${CHRONOMAP_CMAKE_INSTALL_DIR} COMPONENT development)

# pkg-config: the libraries in link order (users first); the static libraries' own dependencies
# under Requires.private and Libs.private (pkg-config --static).
set(CHRONOMAP_PC_LIBS)
foreach(name pipeline view sim render export store ingest_ros align analysis integrate ingest temporal octree core)
  if(name IN_LIST chronomap_modules)
    string(APPEND CHRONOMAP_PC_LIBS " -lchronomap_${name}")
  endif()
endforeach()
string(STRIP "${CHRONOMAP_PC_LIBS}" CHRONOMAP_PC_LIBS)
set(CHRONOMAP_PC_REQUIRES_PRIVATE "tbb libpng libjpeg zlib libzstd liblzf cpp-httplib octomap")
set(CHRONOMAP_PC_LIBS_PRIVATE "-lbz2")
if(CHRONOMAP_DEPS_ROS2)
  string(APPEND CHRONOMAP_PC_REQUIRES_PRIVATE " liblz4 sqlite3")
endif()
if(CHRONOMAP_DEPS_ROS1)
  get_target_property(ros_libraries chronomap_dep::rosbag INTERFACE_LINK_LIBRARIES)
  list(JOIN ros_libraries " " ros_libraries)
  string(APPEND CHRONOMAP_PC_LIBS_PRIVATE " ${ros_libraries}")
endif()
if(CHRONOMAP_HAVE_MPI)
  string(APPEND CHRONOMAP_PC_REQUIRES_PRIVATE " ompi-cxx")
endif()
file(RELATIVE_PATH CHRONOMAP_PC_PREFIX_FROM_PCDIR "/prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/prefix")
configure_file(${PROJECT_SOURCE_DIR}/cmake/chronomap.pc.in ${PROJECT_BINARY_DIR}/package/chronomap.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/package/chronomap.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
        COMPONENT development)

# Man pages from --help (help2man): chronomap(1) and one per command. Required under CI=true, so
# that the Debian package CI builds has them.
find_program(CHRONOMAP_HELP2MAN help2man)
find_program(CHRONOMAP_GZIP gzip)
if(CHRONOMAP_HELP2MAN AND CHRONOMAP_GZIP AND NOT (CHRONOMAP_SANITIZE OR CHRONOMAP_TSAN OR CHRONOMAP_FUZZ))
  set(chronomap_man_default ON)
else()
  set(chronomap_man_default OFF)
endif()
option(CHRONOMAP_MAN_PAGES "Make man pages from --help with help2man" ${chronomap_man_default})
if(NOT CHRONOMAP_MAN_PAGES AND "$ENV{CI}" STREQUAL "true" AND NOT (CHRONOMAP_SANITIZE OR CHRONOMAP_TSAN OR CHRONOMAP_FUZZ))
  message(FATAL_ERROR "help2man (or gzip) not found: run scripts/install-deps.sh (help2man)")
endif()
if(CHRONOMAP_MAN_PAGES)
  set(man_dir ${PROJECT_BINARY_DIR}/man)
  add_custom_command(
    OUTPUT ${man_dir}/chronomap.1.gz
    COMMAND ${CMAKE_COMMAND} -DCLI=$<TARGET_FILE:chronomap_cli> -DHELP2MAN=${CHRONOMAP_HELP2MAN}
            -DGZIP=${CHRONOMAP_GZIP} -DOUTPUT_DIR=${man_dir} -P ${PROJECT_SOURCE_DIR}/cmake/MakeManPages.cmake
    DEPENDS chronomap_cli ${PROJECT_SOURCE_DIR}/cmake/MakeManPages.cmake
    COMMENT "Writing the man pages (help2man)"
    VERBATIM)
  add_custom_target(chronomap_man ALL DEPENDS ${man_dir}/chronomap.1.gz)
  install(DIRECTORY ${man_dir}/ DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT runtime
          FILES_MATCHING PATTERN "*.1.gz")
endif()

# The Debian package: chronomap_VERSION_amd64.deb with every component, its dependencies from
# dpkg-shlibdeps (the CLI's, the shared libraries' and the Python module's).
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME chronomap)
set(CPACK_PACKAGE_VENDOR "chronomap")
set(CPACK_PACKAGE_CONTACT "chronomap maintainers <chronomap@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "four-dimensional maps from RGB-D recordings of one place")
set(CPACK_PACKAGE_DESCRIPTION
    "The chronomap command line (integrate, build, snapshot, diff, predict, view, demo), its C++ libraries (shared and static), headers, CMake package and pkg-config file, the Python module for Debian's python3, and man pages.")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The shared libraries sit beside each other in /usr/lib: dpkg-shlibdeps finds them there.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS ${PROJECT_BINARY_DIR}/src)
# Headers need Eigen and nlohmann/json to compile against; the Python module needs numpy.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "libeigen3-dev, nlohmann-json3-dev")
# The module is built for one Python version (its file name says which).
if(CHRONOMAP_BUILD_PYTHON)
  math(EXPR python_next_minor "${Python_VERSION_MINOR} + 1")
  string(CONCAT CPACK_DEBIAN_PACKAGE_DEPENDS "python3 (>= ${Python_VERSION_MAJOR}.${Python_VERSION_MINOR}), "
                "python3 (<< ${Python_VERSION_MAJOR}.${python_next_minor}), python3-numpy")
endif()
set(CPACK_STRIP_FILES ON)
include(CPack)
