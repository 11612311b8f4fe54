#!/usr/bin/env bash
# The weeks pictures (docs/rhythm.md, docs/alerts.md, docs/colour.md) and their captions' figures
# against what the current code makes (ctest's DocFiguresWeeks, so CI's): three simulations of the
# weeks preset, rhythm_eval, alerts_eval, colour_eval and the pictures' scripts, through
# `scripts/make-doc-images.sh --only weeks --check` with the programs of this build; it fails when
# a figure differs from docs/images/figures.json or a picture from docs/images. About a minute.
#   tests/docs/doc_figures_weeks.sh BUILD_DIR WORK_DIR
set -euo pipefail
build="$1" work="$2"
repo="$(cd "$(dirname "$0")/../.." && pwd)"
rm -rf "$work"
mkdir -p "$work"
exec "$repo/scripts/make-doc-images.sh" --only weeks --build "$build" --no-build --work "$work/work" \
  --images "$work/images" --check
