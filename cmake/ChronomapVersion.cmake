# chronomap/version.h (the version and the optional parts built, for the CLI and the installed
# headers) and the commit the CLI reports, read at every build.
foreach(part ROS1 ROS2 MPI PYTHON)
  set(CHRONOMAP_VERSION_${part} false)
endforeach()
if(CHRONOMAP_DEPS_ROS1)
  set(CHRONOMAP_VERSION_ROS1 true)
endif()
if(CHRONOMAP_DEPS_ROS2)
  set(CHRONOMAP_VERSION_ROS2 true)
endif()
if(CHRONOMAP_HAVE_MPI)
  set(CHRONOMAP_VERSION_MPI true)
endif()
if(CHRONOMAP_BUILD_PYTHON)
  set(CHRONOMAP_VERSION_PYTHON true)
endif()
set(CHRONOMAP_GENERATED_INCLUDE_DIR "${PROJECT_BINARY_DIR}/include")
configure_file("${PROJECT_SOURCE_DIR}/cmake/version.h.in" "${CHRONOMAP_GENERATED_INCLUDE_DIR}/chronomap/version.h" @ONLY)

# `git describe` at build time, not only at configure time: a commit made after configuring is
# the one a build reports. The file is rewritten only when the description changes, so that
# nothing recompiles otherwise.
set(CHRONOMAP_COMMIT_SOURCE "${PROJECT_BINARY_DIR}/generated/commit.cpp")
add_custom_target(chronomap_commit
  COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${PROJECT_SOURCE_DIR} -DOUTPUT=${CHRONOMAP_COMMIT_SOURCE}
          -P ${PROJECT_SOURCE_DIR}/cmake/WriteCommit.cmake
  BYPRODUCTS ${CHRONOMAP_COMMIT_SOURCE}
  COMMENT "Reading the commit (git describe)"
  VERBATIM)
