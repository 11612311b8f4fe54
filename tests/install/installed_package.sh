#!/usr/bin/env bash
# A program outside the project finds an installed chronomap and runs (issue 45): the build is
# installed into a fresh prefix (the runtime and development components; the Python one goes to
# the interpreter's folder and is the Debian package test's), the files a user looks for are
# there, examples/cpp is configured with find_package against it, built and run with the shared
# libraries and again with the static ones, the package's components say what was built, and
# pkg-config gives flags that compile and link.
#   installed_package.sh BUILD_DIR SOURCE_DIR WORK_DIR CXX [COMPILER_LAUNCHER]
set -euo pipefail
build="$1" source="$2" work="$3" cxx="$4" launcher="${5:-}"
rm -rf "$work"
mkdir -p "$work"
prefix="$work/prefix"
for component in runtime development; do
  cmake --install "$build" --prefix "$prefix" --component "$component" >/dev/null
done
libdir="$(sed -n 's/^CMAKE_INSTALL_LIBDIR:PATH=//p' "$build/CMakeCache.txt")"
shared="$(sed -n 's/^CHRONOMAP_SHARED_LIBS:BOOL=//p' "$build/CMakeCache.txt")"
expected=(bin/chronomap include/chronomap/version.h include/chronomap/pipeline/map4d.h "$libdir/libchronomap_core.a"
          "$libdir/cmake/chronomap/chronomapConfig.cmake" "$libdir/cmake/chronomap/chronomapConfigVersion.cmake"
          "$libdir/pkgconfig/chronomap.pc")
[ "$shared" = ON ] && expected+=("$libdir/libchronomap_core.so" "$libdir/libchronomap_pipeline.so")
grep -q '^CHRONOMAP_MAN_PAGES:BOOL=ON' "$build/CMakeCache.txt" && expected+=(share/man/man1/chronomap.1.gz share/man/man1/chronomap-build.1.gz)
for f in "${expected[@]}"; do
  [ -e "$prefix/$f" ] || { echo "missing from the installed prefix: $f"; exit 1; }
done
# (Outputs are read whole before grep: with pipefail, `grep -q` leaving early makes the writer
# die of SIGPIPE and the pipeline fail now and then.)
version_line="$("$prefix/bin/chronomap" --version)"
[ "${version_line%%$'\n'*}" = "chronomap $(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$build/CMakeCache.txt")" ]

# examples/cpp against the prefix: the shared libraries (when installed), then the static ones.
configure=(-G Ninja -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx")
[ -n "$launcher" ] && configure+=(-DCMAKE_CXX_COMPILER_LAUNCHER="$launcher")
kinds=(STATIC)
[ "$shared" = ON ] && kinds=(SHARED STATIC)
for kind in "${kinds[@]}"; do
  static=OFF
  [ "$kind" = STATIC ] && static=ON
  cmake -S "$source/examples/cpp" -B "$work/example_$kind" "${configure[@]}" -DCHRONOMAP_USE_STATIC_LIBS=$static \
    >"$work/configure_$kind.log"
  grep -q "($kind libraries)" "$work/configure_$kind.log" || { cat "$work/configure_$kind.log"; exit 1; }
  cmake --build "$work/example_$kind" >/dev/null
  "$work/example_$kind/four_d_map" "$work/run_$kind" | tee "$work/run_$kind.txt"
  # Two sessions: two snapshots, each with occupied and free voxels.
  [ "$(grep -cE '^snapshot at [0-9.]+: [1-9][0-9]* occupied voxels, [1-9][0-9]* free voxels' "$work/run_$kind.txt")" = 2 ]
  grep -q "^chronomap .*: 2 sessions" "$work/run_$kind.txt"
done
if [ "$shared" = ON ]; then
  # The shared build links chronomap's libraries, the static one does not.
  shared_libs="$(ldd "$work/example_SHARED/four_d_map")" static_libs="$(ldd "$work/example_STATIC/four_d_map")"
  grep -q "libchronomap_pipeline.so" <<<"$shared_libs"
  ! grep -q "libchronomap_" <<<"$static_libs"
fi

# Components: the parts this build has are found, one it cannot have fails find_package.
parts=()
version_h="$prefix/include/chronomap/version.h"
grep -q 'kBuiltWithRos1 = true' "$version_h" && parts+=(ros1)
grep -q 'kBuiltWithRos2Storage = true' "$version_h" && parts+=(ros2)
grep -q 'kBuiltWithMpi = true' "$version_h" && parts+=(mpi)
grep -q 'kBuiltWithPython = true' "$version_h" && parts+=(python)
mkdir -p "$work/components"
cat >"$work/components/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.22)
project(components NONE)
find_package(chronomap CONFIG REQUIRED COMPONENTS ${PARTS})
CMAKE
cmake -S "$work/components" -B "$work/components/found" -DCMAKE_PREFIX_PATH="$prefix" "-DPARTS=$(IFS=';'; echo "${parts[*]}")" >/dev/null
if cmake -S "$work/components" -B "$work/components/missing" -DCMAKE_PREFIX_PATH="$prefix" -DPARTS=nosuchpart \
     >"$work/components/missing.log" 2>&1; then
  echo "find_package(chronomap COMPONENTS nosuchpart) succeeded"
  exit 1
fi

# pkg-config: the version, and flags that compile and link a program.
export PKG_CONFIG_PATH="$prefix/$libdir/pkgconfig"
[ "$(pkg-config --modversion chronomap)" = "$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$build/CMakeCache.txt")" ]
printf '#include <cstdio>\n#include "chronomap/version.h"\nint main() { std::printf("%%s\\n", chronomap::kVersion); }\n' \
  >"$work/pc.cpp"
# shellcheck disable=SC2046
"$cxx" -std=c++20 $(pkg-config --cflags chronomap) "$work/pc.cpp" -o "$work/pc" $(pkg-config --libs chronomap)
[ "$(LD_LIBRARY_PATH="$prefix/$libdir" "$work/pc")" = "$(pkg-config --modversion chronomap)" ]
echo "installed package: OK"
