#!/usr/bin/env bash
# The Foxglove export read back by Foxglove's own readers (ctest runs it):
#   tests/export/foxglove/run.sh CLI WORKDIR
# Simulates the tiny preset (three sessions at a quarter of its resolution), builds its 4D map,
# exports it as MCAP and checks the file with read_mcap.mjs (@mcap/core, @foxglove/schemas from
# the committed lock, installed with npm ci into WORKDIR). Without node or npm it is skipped
# (exit code 77), except under CI=true, where scripts/install-deps.sh has installed them and a
# missing one is a failure.
set -euo pipefail
cli="$1" work="$2"
src="$(cd "$(dirname "$0")" && pwd)"
missing=()
command -v node >/dev/null || missing+=(node)
command -v npm >/dev/null || missing+=(npm)
source "$src/../../support/missing_tools.sh"
skip_or_fail_missing "${missing[@]}"
mkdir -p "$work"
for f in package.json package-lock.json read_mcap.mjs; do cp "$src/$f" "$work/$f"; done
# npm ci once per lock: node_modules/.chronomap-lock is the lock it was installed from.
if ! cmp -s "$work/package-lock.json" "$work/node_modules/.chronomap-lock"; then
  (cd "$work" && npm ci --no-audit --no-fund >/dev/null)
  cp "$work/package-lock.json" "$work/node_modules/.chronomap-lock"
fi
data="$work/data"
rm -rf "$data"
"$cli" simulate --preset tiny --resolution-scale 0.25 -o "$data/sim" >/dev/null
"$cli" build "$data/map.cmap" "$data"/sim/session_0* --fast --threads 1 >/dev/null
"$cli" export "$data/map.cmap" -o "$data/map.mcap"
exec node "$work/read_mcap.mjs" "$cli" "$data/map.cmap" "$data/map.mcap"
