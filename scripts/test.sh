#!/usr/bin/env bash
# Builds and runs every test: a release build with warnings as errors, then the same suite under
# AddressSanitizer + UndefinedBehaviorSanitizer, then the multi-threaded tests (integration,
# registration, the simulator's threaded renderer) under ThreadSanitizer; the simulator's long
# scenario tests and the keep-mean and fine-radius registration tests (serial code on top of the threaded rounds,
# about a minute under TSan) use the same threads and run only in the other two. Set
# CHRONOMAP_SKIP_SANITIZERS=1 to skip the sanitizer runs.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each step's wall time, so that CI's time (kept under 40 minutes) can be seen where it goes.
step_start=$SECONDS
step_done() {
  echo "test.sh: $1 took $((SECONDS - step_start)) s (total $SECONDS s)"
  step_start=$SECONDS
}
scripts/install-deps.sh
scripts/check-architecture.sh
step_done "installing and the architecture check"
jobs="$(nproc)"
cmake --preset ci >/dev/null
cmake --build --preset ci -j"$jobs"
step_done "the release build"
ctest --preset ci -j"$jobs"
step_done "the release tests"
if [ "${CHRONOMAP_SKIP_SANITIZERS:-0}" != 1 ]; then
  cmake --preset asan >/dev/null
  cmake --build --preset asan -j"$jobs"
  step_done "the ASan + UBSan build"
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 ctest --preset asan -j"$jobs"
  step_done "the ASan + UBSan tests"
  cmake --preset tsan >/dev/null
  cmake --build --preset tsan -j"$jobs" --target chronomap_threaded_tests
  step_done "the TSan build"
  TSAN_OPTIONS="halt_on_error=1 suppressions=$PWD/tests/tsan.supp" \
    ctest --preset tsan -j"$jobs" -R '^(Integrator|RegisterSessions|Simulator)\.' \
      -E '^Simulator\.(TheWeeksPreset|ChangeEvents|RareEvents)|^RegisterSessions\.(KeepMean|FineRadius)'
  step_done "the TSan tests"
fi
