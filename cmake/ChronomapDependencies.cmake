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

add_library(chronomap_octomap INTERFACE)
target_include_directories(chronomap_octomap SYSTEM INTERFACE ${OCTOMAP_INCLUDE_DIRS})
target_link_libraries(chronomap_octomap INTERFACE ${OCTOMAP_LIBRARIES})

# cpp-httplib (the viewer's server): Debian builds it as a library with TLS and compression,
# and its header must be compiled with the same definitions, which pkg-config gives.
find_package(PkgConfig REQUIRED)
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
