#!/usr/bin/env bash
# Installs chronomap's build and test dependencies from Debian's packages, when any is missing.
set -euo pipefail
packages=(build-essential cmake pkg-config libeigen3-dev libtbb-dev libcli11-dev nlohmann-json3-dev
          libpng-dev libjpeg62-turbo-dev zlib1g-dev libbz2-dev libzstd-dev liblzf-dev liboctomap-dev libgtest-dev
          libbenchmark-dev pybind11-dev python3-dev python3-numpy python3-pytest python3-open3d python3-matplotlib
          python3-pip python3-venv python3-build libcpp-httplib-dev chromium
          # ROS 1 bags: librosbag and the generated message headers; the tests write bags with
          # Debian's python3-rosbag and read the simulator's PNGs with python3-pil.
          librosbag-dev libsensor-msgs-dev libgeometry-msgs-dev libnav-msgs-dev libtf2-msgs-dev
          python3-rosbag python3-sensor-msgs python3-geometry-msgs python3-nav-msgs python3-tf2-msgs python3-pil
          # ROS 2 bags: MCAP chunks in lz4 (zstd above), and the SQLite storage (.db3); lz4 also
          # builds UFOMap inside bench/integrate_vs_peers (../shared/peers).
          liblz4-dev libsqlite3-dev
          # MPI: `mpirun -np N chronomap build` (optional at build time; CI builds and tests it).
          libopenmpi-dev openmpi-bin
          # The Debian package (CPack): man pages from --help, and dpkg-shlibdeps for its dependencies.
          help2man dpkg-dev)
# The viewer's tests run node (three.js, esbuild and puppeteer-core come from npm, viewer/
# package-lock.json); any node 18 or newer will do, Debian's when none is installed.
command -v node >/dev/null || packages+=(nodejs)
command -v npm >/dev/null || packages+=(npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "installing: ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
