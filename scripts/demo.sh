#!/usr/bin/env bash
# The main job: install dependencies, build chronomap, and integrate the real study-room frames
# of ../shared/data/3dmatch into a session map, exported to PLY and OctoMap. (Until the
# simulator lands, this stands in for `chronomap demo`.)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)"
data="${CHRONOMAP_DATA_DIR:-../shared/data}"
out="${1:-out}"
mkdir -p "$out"
bin=build/release/apps/chronomap/chronomap
"$bin" integrate "$data/3dmatch/3dmatch" -o "$out/room.cmap"
"$bin" stats "$out/room.cmap"
"$bin" export "$out/room.cmap" -o "$out/room.ply"
"$bin" export "$out/room.cmap" -o "$out/room.ot"
"$bin" export "$out/room.cmap" -o "$out/room.png" --scale 4
echo "open $out/room.png (top view), $out/room.ply in any point-cloud viewer, or $out/room.ot in octovis"
