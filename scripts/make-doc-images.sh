#!/usr/bin/env bash
# Every picture of README.md and docs/ from the current code and the simulator's fixed seeds, and
# the figures their captions quote (docs/images/figures.json, checked by ctest's DocFigures):
#
#   scripts/make-doc-images.sh [--only GROUP,...] [--work DIR] [--build DIR]
#
# GROUP (default: office,viewer,room,python,architecture):
#   office        chronomap demo (seed 1, 320 x 240): office_topview.png, office_changes_00_01.png
#                 (the pair of sessions 1 and 2), office_frame_rgb.png, office_frame_depth.png
#   viewer        chronomap view on the demo's map, viewer/test/shoot.mjs in headless Chromium:
#                 viewer_office_diff.png, _move.png, _history.png, _predicted.png (needs office)
#   room          the 3DMatch study room (../shared/data, or CHRONOMAP_DATA_DIR): room_topview.png,
#                 and upright (--up auto) with a Kinect cloud of pcl-kinect: frames_*.png
#   python        examples/show_changes.py on the demo's map: python_show_changes.png (needs office)
#   architecture  Graphviz's dot on docs/images/architecture.dot: architecture.png
# Not made by this script yet (their own programs say how; their captions' figures are kept in
# figures.json as the pictures were measured, marked "measured": null): floor66_storage.png and
# viewer_floor66_zoom.png (bench/temporal and shoot.mjs on the floor66 preset, about an hour on
# 2 cores), alerts_night.png, weeks_predicted_vs_true.png (bench/rhythm_picture.py) and
# colour_predicted_vs_true.png (bench/colour_picture.py) on the weeks preset.
#
# Builds chronomap and the Python module in build/release (cmake --preset release), or in the
# configured build folder --build names. The office groups take about 2 minutes after the build
# on 2 cores. --work keeps what they made (the demo's folder, the viewer's shots) in DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
repo="$PWD"
groups="office,viewer,room,python,architecture"
work=""
build=""
while (($#)); do
  case "$1" in
    --only) groups="$2"; shift 2 ;;
    --work) work="$2"; shift 2 ;;
    --build) build="$(realpath "$2")"; shift 2 ;;
    -h|--help) sed -n '2,25p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-doc-images.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
has() { [[ ",$groups," == *",$1,"* ]]; }
for g in ${groups//,/ }; do
  case "$g" in office|viewer|room|python|architecture) ;;
    *) echo "make-doc-images.sh: no group '$g' (office, viewer, room, python, architecture)" >&2; exit 2 ;;
  esac
done
missing=()
has viewer && { command -v node >/dev/null || missing+=(nodejs); command -v chromium >/dev/null || missing+=(chromium); }
has architecture && { command -v dot >/dev/null || missing+=(graphviz); }
if ((${#missing[@]})); then
  echo "make-doc-images.sh: missing ${missing[*]} (apt-get install ${missing[*]}, or leave the group out with --only)" >&2
  exit 1
fi
if [ -z "$work" ]; then
  work="$(mktemp -d)"
  trap 'rm -rf "$work"' EXIT
fi
mkdir -p "$work"
images="$repo/docs/images"
data="${CHRONOMAP_DATA_DIR:-$repo/../shared/data}"

if [ -z "$build" ]; then
  cmake --preset release >/dev/null
  build="$repo/build/release"
fi
targets=(--target chronomap_cli)
has python && targets+=(--target _chronomap)
cmake --build "$build" -j"${CMAKE_BUILD_PARALLEL_LEVEL:-$(nproc)}" "${targets[@]}"
cli="$build/apps/chronomap/chronomap"
measure=()

if has office || has viewer || has python; then
  echo "== office: chronomap demo"
  "$cli" demo -o "$work/demo" >/dev/null
  measure+=(--demo "$work/demo")
fi
if has office; then
  cp "$work/demo/images/map_topview.png" "$images/office_topview.png"
  cp "$work/demo/images/diff_01_02.png" "$images/office_changes_00_01.png"
  cp "$work/demo/images/frame_rgb.png" "$images/office_frame_rgb.png"
  cp "$work/demo/images/frame_depth.png" "$images/office_frame_depth.png"
fi

if has viewer; then
  echo "== viewer: chronomap view and shoot.mjs"
  (cd viewer && { [ -d node_modules ] && [ node_modules -nt package-lock.json ] || npm ci --no-audit --no-fund >/dev/null; })
  "$cli" view "$work/demo/office.cmap" --port 0 >"$work/view.log" 2>&1 &
  server=$!
  url=""
  for _ in $(seq 100); do
    url="$(grep -o 'http://127\.0\.0\.1:[0-9]*/' "$work/view.log" | head -1 || true)"
    [ -n "$url" ] && break
    sleep 0.2
  done
  [ -n "$url" ] || { cat "$work/view.log" >&2; kill "$server"; exit 1; }
  status=0
  CHROMIUM="${CHROMIUM:-$(command -v chromium || command -v chromium-browser)}" \
    node viewer/test/shoot.mjs "$url" "$work/shot" >"$work/shots.json" || status=$?
  kill "$server"
  wait "$server" 2>/dev/null || true
  ((status == 0)) || exit "$status"
  for view in diff move history predicted; do
    cp "$work/shot-$view.png" "$images/viewer_office_$view.png"
  done
  # The page lists the objects of the one call the demo's report lists (FrontDoors checks it too).
  python3 - "$work/shots.json" "$work/demo/report.json" <<'EOF'
import json, sys
shots, report = (json.load(open(p)) for p in sys.argv[1:])
first = report["pairs"][0]["objects"]
assert shots["objects"] == len(first), f"the viewer lists {shots['objects']} objects, the demo {len(first)}"
EOF
fi

if has room; then
  echo "== room: the 3DMatch study room"
  "$cli" integrate "$data/3dmatch/3dmatch" --resolution 0.04 --max-range 6 -o "$work/room.cmap" --json \
    >"$work/room.json"
  "$cli" export "$work/room.cmap" -o "$images/room_topview.png" >/dev/null
  # The same frames upright (docs/frames.md): 3DMatch's world has +y up, which --up auto finds.
  "$cli" integrate "$data/3dmatch/3dmatch" --resolution 0.04 --max-range 6 --up auto -o "$work/room_up.cmap" >/dev/null
  "$cli" export "$work/room_up.cmap" -o "$images/frames_room_up.png" >/dev/null
  # One Kinect cloud in its optical frame (y down, z forward), as recorded and with --up auto (-y).
  "$cli" integrate "$data/pcl-kinect/office1.pcd" --max-range 6 -o "$work/office1.cmap" >/dev/null
  "$cli" export "$work/office1.cmap" -o "$images/frames_office1_recorded.png" >/dev/null
  "$cli" integrate "$data/pcl-kinect/office1.pcd" --max-range 6 --up auto -o "$work/office1_up.cmap" >/dev/null
  "$cli" export "$work/office1_up.cmap" -o "$images/frames_office1_up.png" >/dev/null
  measure+=(--room "$work/room.json")
fi

if has python; then
  echo "== python: examples/show_changes.py"
  PYTHONPATH="$build/python" /usr/bin/python3 examples/show_changes.py "$work/demo/office.cmap" \
    -o "$work/show" >/dev/null
  cp "$work/show/top_view.png" "$images/python_show_changes.png"
fi

if has architecture; then
  echo "== architecture: dot"
  dot -Tpng "$images/architecture.dot" -o "$images/architecture.png"
fi

python3 scripts/doc_figures.py measure "$images/figures.json" "${measure[@]}"
python3 scripts/doc_figures.py check "$images/figures.json"
