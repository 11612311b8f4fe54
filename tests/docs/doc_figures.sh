#!/usr/bin/env bash
# The figures the captions of README.md and docs/ quote against what the current code measures
# (ctest's DocFigures, so CI's): chronomap demo at its defaults (seed 1, 320 x 240, the run
# scripts/make-doc-images.sh makes the office's pictures from; about 20 s), the study room's
# integration as recorded and with --up auto, and pcl-kinect's office1 with --up auto (1 s each),
# then scripts/doc_figures.py check against docs/images/figures.json.
#   tests/docs/doc_figures.sh CLI WORKDIR [DATA_DIR]
# Without the study room's frames or office1.pcd (CHRONOMAP_DATA_DIR, else DATA_DIR: the build's
# CHRONOMAP_DATA_DIR, by default ../shared/data) it is skipped (77),
# except under CI=true, where a missing file is a failure.
set -euo pipefail
cli="$1"
work="$2"
repo="$(cd "$(dirname "$0")/../.." && pwd)"
data="${CHRONOMAP_DATA_DIR:-${3:-$repo/../shared/data}}"
room="$data/3dmatch/3dmatch"
office1="$data/pcl-kinect/office1.pcd"
for need in "$room" "$office1"; do
  if [ ! -e "$need" ]; then
    if [ "${CI:-}" = true ]; then
      echo "missing: $need" >&2
      exit 1
    fi
    echo "skipped: $need missing"
    exit 77
  fi
done
rm -rf "$work"
mkdir -p "$work"
"$cli" demo -o "$work/demo" >/dev/null
"$cli" integrate "$room" --resolution 0.04 --max-range 6 -o "$work/room.cmap" --json >"$work/room.json"
"$cli" integrate "$room" --resolution 0.04 --max-range 6 --up auto -o "$work/room_up.cmap" --json >"$work/room_up.json"
"$cli" integrate "$office1" --max-range 6 --up auto -o "$work/office1_up.cmap" --json >"$work/office1_up.json"
python3 "$repo/scripts/doc_figures.py" check "$repo/docs/images/figures.json" --demo "$work/demo" --room "$work/"
