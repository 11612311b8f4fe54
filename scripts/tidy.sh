#!/usr/bin/env bash
# Runs clang-tidy with the checked-in .clang-tidy over the library and the command line (src/,
# apps/), on every core; exits non-zero on any finding. About 13 minutes of CPU time.
# Usage: scripts/tidy.sh [FILE-REGEX]   (default: 'src/|apps/')
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
if ! command -v run-clang-tidy >/dev/null; then
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends clang-tidy >/dev/null
fi
cmake --preset release >/dev/null  # writes build/release/compile_commands.json
run-clang-tidy -p build/release -j "$(nproc)" -quiet "${1:-src/|apps/}"
