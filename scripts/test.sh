#!/usr/bin/env bash
# Builds and runs every test: a release build with warnings as errors, then the same suite under
# AddressSanitizer + UndefinedBehaviorSanitizer. Set CHRONOMAP_SKIP_SANITIZERS=1 to skip the second.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
jobs="$(nproc)"
cmake --preset ci >/dev/null
cmake --build --preset ci -j"$jobs"
ctest --preset ci -j"$jobs"
if [ "${CHRONOMAP_SKIP_SANITIZERS:-0}" != 1 ]; then
  cmake --preset asan >/dev/null
  cmake --build --preset asan -j"$jobs"
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 ctest --preset asan -j"$jobs"
fi
