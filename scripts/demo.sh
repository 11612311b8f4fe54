#!/usr/bin/env bash
# The main job: install dependencies, build chronomap, and run `chronomap demo`: simulate the
# office preset, integrate every session, build the 4D map and write OUT/report.md with pictures.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)"
out="${1:-out}"
build/release/apps/chronomap/chronomap demo -o "$out"
