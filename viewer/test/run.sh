#!/usr/bin/env bash
# The viewer's tests that need node (ctest runs them):
#   viewer/test/run.sh bundle                 the committed bundle is the one viewer/src builds
#   viewer/test/run.sh browser CLI WORKDIR    the page in headless Chromium (browser_test.mjs)
# Without node, npm or Chromium they are skipped (exit code 77), except under CI=true, where
# scripts/install-deps.sh has installed them and a missing one is a failure.
set -euo pipefail
mode="$1"
shift
cd "$(dirname "$0")/.."
missing=()
command -v node >/dev/null || missing+=(node)
command -v npm >/dev/null || missing+=(npm)
chromium="${CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}"
[ "$mode" = bundle ] || [ -n "$chromium" ] || missing+=(chromium)
source ../tests/support/missing_tools.sh
skip_or_fail_missing "${missing[@]}"
if [ ! -d node_modules ] || [ package-lock.json -nt node_modules ]; then
  npm ci --no-audit --no-fund >/dev/null
fi
case "$mode" in
  bundle) exec ./build.sh --check ;;
  browser)
    rm -rf "$2"
    CHROMIUM="$chromium" exec node test/browser_test.mjs "$1" "$2" ;;
  *) echo "usage: viewer/test/run.sh bundle | browser CLI WORKDIR" >&2; exit 2 ;;
esac
