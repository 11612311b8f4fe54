#!/usr/bin/env bash
# The Debian package (issue 45): CPack makes chronomap_VERSION_amd64.deb from the build, with its
# dependencies from dpkg-shlibdeps; it holds the CLI, the libraries, the headers, the CMake
# package, the pkg-config file, the Python module and the man pages. It is installed with
# `dpkg --root ROOT -i` into a throwaway root with its own package database (this machine's
# database and files do not change; no container is needed; its dependencies are checked
# against this machine's database, which the root's empty one cannot do, hence --force-depends),
# `chronomap demo` runs from the root's PATH, and `dpkg --root ROOT -r` removes every file it
# installed. The CLI and the Python module link chronomap's static libraries, so neither needs LD_LIBRARY_PATH; the shared libraries find each
# other beside themselves ($ORIGIN).
#   debian_package.sh BUILD_DIR WORK_DIR
# Exits 77 (skipped) without dpkg-deb, dpkg-shlibdeps, the man pages or root rights, except under
# CI=true.
set -euo pipefail
build="$1" work="$2"
missing=""
command -v dpkg-deb >/dev/null || missing+=" dpkg-deb"
command -v dpkg-shlibdeps >/dev/null || missing+=" dpkg-shlibdeps (dpkg-dev)"
grep -q '^CHRONOMAP_MAN_PAGES:BOOL=ON' "$build/CMakeCache.txt" || missing+=" help2man"
# dpkg installs only as root, even into a throwaway root (CI runs as root).
[ "$(id -u)" = 0 ] || missing+=" root rights (dpkg installs only as root)"
if [ -n "$missing" ]; then
  echo "the Debian package needs:$missing (scripts/install-deps.sh installs them)"
  [ "${CI:-}" = true ] && exit 1
  exit 77
fi
version="$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$build/CMakeCache.txt")"
rm -rf "$work"
mkdir -p "$work"
start=$SECONDS
(cd "$work" && cpack --config "$build/CPackConfig.cmake" -B "$work" >"$work/cpack.log" 2>&1) || { cat "$work/cpack.log"; exit 1; }
deb="$work/chronomap_${version}_amd64.deb"
[ -f "$deb" ] || { echo "no $deb"; ls "$work"; exit 1; }
echo "made $(basename "$deb") ($(du -k "$deb" | cut -f1) KiB) in $((SECONDS - start)) s"

# What it holds.
dpkg-deb -c "$deb" | awk '{ if ($(NF-1) == "->") print $(NF-2); else print $NF }' >"$work/contents.txt"
for f in ./usr/bin/chronomap ./usr/lib/libchronomap_core.a ./usr/lib/libchronomap_pipeline.so \
         ./usr/include/chronomap/version.h ./usr/lib/cmake/chronomap/chronomapConfig.cmake \
         ./usr/lib/pkgconfig/chronomap.pc ./usr/share/man/man1/chronomap.1.gz ./usr/share/man/man1/chronomap-demo.1.gz \
         ./usr/lib/python3/dist-packages/chronomap/__init__.py; do
  grep -qx "$f" "$work/contents.txt" || { echo "the package lacks $f"; exit 1; }
done
# Dependencies from dpkg-shlibdeps (TBB, libpng, ...), each installed on this machine.
depends="$(dpkg-deb -f "$deb" Depends)"
echo "Depends: $depends"
for p in libtbb libpng python3-numpy; do
  grep -q "$p" <<<"$depends" || { echo "Depends lacks $p"; exit 1; }
done
tr ',' '\n' <<<"$depends" | sed 's/|.*//; s/(.*//; s/ //g' | while read -r p; do
  status="$(dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null || true)"
  grep -q "install ok installed" <<<"$status" || { echo "dependency $p not installed"; exit 1; }
done

# Installed into a throwaway root with its own package database, run from its PATH. The
# maintainer scripts (ldconfig) run outside the root (--force-script-chrootless): the root has
# no shell to run them in.
root="$work/root"
mkdir -p "$root/var/lib/dpkg/info" "$root/var/lib/dpkg/updates"
touch "$root/var/lib/dpkg/status"
dpkg_root=(dpkg --root="$root" --log="$work/dpkg-actions.log" --force-depends --force-script-chrootless)
"${dpkg_root[@]}" -i "$deb" >"$work/dpkg.log" 2>&1 || { cat "$work/dpkg.log"; exit 1; }
[ "$(dpkg-query --root="$root" -W -f='${Status} ${Version}' chronomap)" = "install ok installed $version" ] ||
  { echo "dpkg did not record chronomap $version as installed"; exit 1; }
export PATH="$root/usr/bin:$PATH"
[ "$(command -v chronomap)" = "$root/usr/bin/chronomap" ]
version_line="$(chronomap --version)"
[ "${version_line%%$'\n'*}" = "chronomap $version" ]
if grep -q "libchronomap_\|not found" <<<"$(ldd "$root/usr/bin/chronomap")"; then
  ldd "$root/usr/bin/chronomap"
  exit 1
fi
if ldd "$root/usr/lib/libchronomap_pipeline.so" | grep "not found"; then exit 1; fi
PYTHONPATH="$root/usr/lib/python3/dist-packages" /usr/bin/python3 -c \
  "import chronomap, sys; assert chronomap.__file__.startswith('$root'), chronomap.__file__"
start=$SECONDS
chronomap demo --resolution-scale 0.2 -o "$work/demo" >"$work/demo.log" 2>&1 || { tail -20 "$work/demo.log"; exit 1; }
[ -s "$work/demo/report.md" ] || { echo "chronomap demo wrote no report.md"; exit 1; }
echo "chronomap demo --resolution-scale 0.2 from the package: $((SECONDS - start)) s"
# Removed: none of its files is left in the root.
"${dpkg_root[@]}" -r chronomap >>"$work/dpkg.log" 2>&1 || { cat "$work/dpkg.log"; exit 1; }
left="$(find "$root" -path "$root/var/lib/dpkg" -prune -o ! -type d -print | head -5)"
[ -z "$left" ] || { echo "dpkg -r left files: $left"; exit 1; }
echo "Debian package: OK"
