#!/usr/bin/env bash
# Rebuilds the viewer's bundle, viewer/dist/viewer.js, from viewer/src with the locked npm
# packages (three.js, esbuild). The bundle is committed, so that building chronomap never needs
# npm; run this after changing viewer/src and commit both. `viewer/build.sh --check` rebuilds
# into a temporary file and fails when it differs from the committed bundle (CI runs it).
set -euo pipefail
cd "$(dirname "$0")"
if [ ! -d node_modules ] || [ package-lock.json -nt node_modules ]; then
  npm ci --no-audit --no-fund >/dev/null
fi
out=dist/viewer.js
if [ "${1:-}" = --check ]; then
  out="$(mktemp --suffix=.js)"
  trap 'rm -f "$out"' EXIT
fi
npx esbuild src/main.js --bundle --minify --format=iife --target=es2020 --legal-comments=none \
  --log-level=warning --outfile="$out"
if [ "${1:-}" = --check ]; then
  if ! cmp -s "$out" dist/viewer.js; then
    echo "viewer/dist/viewer.js does not match viewer/src: run viewer/build.sh and commit the bundle" >&2
    exit 1
  fi
  echo "viewer/dist/viewer.js matches viewer/src"
fi
