#!/usr/bin/env bash
# Every picture of README.md and docs/ from the current code and the simulator's fixed seeds, and
# the figures their captions quote (docs/images/figures.json, checked by ctest's DocFigures):
#
#   scripts/make-doc-images.sh [--only GROUP,...] [--work DIR] [--build DIR] [--no-build]
#                              [--images DIR] [--check]
#
# GROUP (default: office,viewer,room,python,architecture; weeks, floor66 and year only when named):
#   office        chronomap demo (seed 1, 320 x 240): office_topview.png, office_changes_00_01.png
#                 (the pair of sessions 1 and 2), office_frame_rgb.png, office_frame_depth.png
#   viewer        chronomap view on the demo's map, viewer/test/shoot.mjs in headless Chromium:
#                 viewer_office_diff.png, _move.png, _history.png, _predicted.png (needs office)
#   room          the 3DMatch study room (../shared/data, or CHRONOMAP_DATA_DIR): room_topview.png,
#                 and upright (--up auto) with a Kinect cloud of pcl-kinect: frames_*.png
#   python        examples/show_changes.py on the demo's map: python_show_changes.png (needs office)
#   architecture  Graphviz's dot on docs/images/architecture.dot: architecture.png
#   weeks         the weeks preset (seed 1, 0.25 of 640 x 480, true poses), three simulations:
#                 weeks_predicted_vs_true.png (rhythm_eval --save-map, chronomap costmap,
#                 bench/rhythm_picture.py), alerts_night.png (alerts_eval --map with rare events,
#                 chronomap alerts -o) and colour_predicted_vs_true.png (colour_eval --out with
#                 daylight and a repaint, bench/colour_picture.py); about 2 minutes
#   floor66       the floor66 preset (66 sessions, 0.5 of 640 x 480): floor66_storage.png
#                 (bench/temporal --sim --plot) and viewer_floor66_zoom.png (chronomap build,
#                 chronomap view, shoot.mjs); about 5 minutes on 2 cores
#   year          bench/scale --plot-from docs/images/year_nights.json: year_nights.png, the nights
#                 of the year run that docs/scale.md describes (the run itself, over an hour, is
#                 bench/scale's; its output is kept in that file); a second
#                 (year_one_floor_windows.png) from year_one_floor_windows.json, the year of one
#                 floor with history windows; year_one_floor_windowed and year_windowed, the years
#                 of one floor and of the site's three floors with tiles kept as windows;
#                 year_site_windowed, the site's year again with staggered first windows and
#                 the folder no longer listed on every write
#
# Builds chronomap and the Python module (and, for weeks and floor66, the benchmark programs) in
# build/release (cmake --preset release), or in the configured build folder --build names. The
# office groups take about 2 minutes after the build on 2 cores. --work keeps what they made (the
# demo's folder, the viewer's shots, the simulations) in DIR. --no-build runs the programs already
# built in --build. --images DIR writes the pictures there instead of docs/images. --check (with
# --images) changes nothing in docs/: it fails when a figure the groups measured differs from
# docs/images/figures.json or a picture they made differs, byte for byte, from the one in
# docs/images (the viewer's screenshots are not compared: the browser's drawing varies). ctest's
# DocFiguresWeeks runs `--only weeks --check`.
set -euo pipefail
caller="$PWD"
# A path as the caller meant it (relative to where the script was started), made absolute.
absolute() { case "$1" in /*) printf '%s\n' "$1" ;; *) printf '%s\n' "$caller/$1" ;; esac; }
cd "$(dirname "$0")/.."
repo="$PWD"
groups="office,viewer,room,python,architecture"
work=""
build=""
images="$repo/docs/images"
no_build=0
check=0
while (($#)); do
  case "$1" in
    --only) groups="$2"; shift 2 ;;
    --images) images="$(absolute "$2")"; mkdir -p "$images"; images="$(realpath "$images")"; shift 2 ;;
    --no-build) no_build=1; shift ;;
    --check) check=1; shift ;;
    --work) work="$(absolute "$2")"; shift 2 ;;
    --build) build="$(realpath "$(absolute "$2")")"; shift 2 ;;
    -h|--help) sed -n '2,34p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-doc-images.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
if ((check)) && [ "$images" = "$repo/docs/images" ]; then
  echo "make-doc-images.sh: --check compares what it makes with docs/images: give --images another folder" >&2
  exit 2
fi
has() { [[ ",$groups," == *",$1,"* ]]; }
for g in ${groups//,/ }; do
  case "$g" in office|viewer|room|python|architecture|weeks|floor66|year) ;;
    *) echo "make-doc-images.sh: no group '$g' (office, viewer, room, python, architecture, weeks, floor66, year)" >&2
       exit 2 ;;
  esac
done
missing=()
{ has viewer || has floor66; } && { command -v node >/dev/null || missing+=(nodejs); command -v chromium >/dev/null || missing+=(chromium); }
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
touch "$work/.started"
data="${CHRONOMAP_DATA_DIR:-$repo/../shared/data}"

benches=()
has weeks && benches+=(rhythm_eval alerts_eval colour_eval)
has floor66 && benches+=(temporal)
has year && benches+=(scale)
if ((no_build)) && [ -z "$build" ]; then
  echo "make-doc-images.sh: --no-build needs --build DIR" >&2
  exit 2
elif [ -z "$build" ]; then
  if ((${#benches[@]})); then cmake --preset release -DCHRONOMAP_BUILD_BENCH=ON >/dev/null
  else cmake --preset release >/dev/null; fi
  build="$repo/build/release"
elif ((${#benches[@]})) && ! grep -Eqi '^CHRONOMAP_BUILD_BENCH:BOOL=(ON|1|TRUE|YES|Y)$' "$build/CMakeCache.txt"; then
  echo "make-doc-images.sh: the weeks, floor66 and year groups need $build configured with -DCHRONOMAP_BUILD_BENCH=ON" >&2
  exit 1
fi
targets=(--target chronomap_cli)
{ has python || has weeks; } && targets+=(--target _chronomap)
for b in "${benches[@]}"; do targets+=(--target "$b"); done
((no_build)) || cmake --build "$build" -j"${CMAKE_BUILD_PARALLEL_LEVEL:-$(nproc)}" "${targets[@]}"
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

# shoot MAP PREFIX: chronomap view on MAP, viewer/test/shoot.mjs's pictures as PREFIX-*.png and its
# figures as PREFIX.json.
shoot() {
  (cd viewer && { [ -d node_modules ] && [ node_modules -nt package-lock.json ] || npm ci --no-audit --no-fund >/dev/null; })
  "$cli" view "$1" --port 0 >"$2-view.log" 2>&1 &
  local server=$! url="" status=0
  for _ in $(seq 600); do
    url="$(grep -o 'http://127\.0\.0\.1:[0-9]*/' "$2-view.log" | head -1 || true)"
    [ -n "$url" ] && break
    sleep 0.2
  done
  [ -n "$url" ] || { cat "$2-view.log" >&2; kill "$server"; exit 1; }
  CHROMIUM="${CHROMIUM:-$(command -v chromium || command -v chromium-browser)}" \
    node viewer/test/shoot.mjs "$url" "$2" >"$2.json" || status=$?
  kill "$server"
  wait "$server" 2>/dev/null || true
  ((status == 0)) || exit "$status"
}

if has viewer; then
  echo "== viewer: chronomap view and shoot.mjs"
  shoot "$work/demo/office.cmap" "$work/shot"
  cp "$work/shot.json" "$work/shots.json"
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
  mkdir -p "$work/room"
  r="$work/room"
  "$cli" integrate "$data/3dmatch/3dmatch" --resolution 0.04 --max-range 6 -o "$r/room.cmap" --json >"$r/room.json"
  "$cli" export "$r/room.cmap" -o "$images/room_topview.png" >/dev/null
  # The same frames upright (docs/frames.md): 3DMatch's world has +y up, which --up auto finds.
  "$cli" integrate "$data/3dmatch/3dmatch" --resolution 0.04 --max-range 6 --up auto -o "$r/room_up.cmap" --json \
    >"$r/room_up.json"
  "$cli" export "$r/room_up.cmap" -o "$images/frames_room_up.png" >/dev/null
  # One Kinect cloud in its optical frame (y down, z forward), as recorded and with --up auto (-y).
  "$cli" integrate "$data/pcl-kinect/office1.pcd" --max-range 6 -o "$r/office1.cmap" >/dev/null
  "$cli" export "$r/office1.cmap" -o "$images/frames_office1_recorded.png" >/dev/null
  "$cli" integrate "$data/pcl-kinect/office1.pcd" --max-range 6 --up auto -o "$r/office1_up.cmap" --json \
    >"$r/office1_up.json"
  "$cli" export "$r/office1_up.cmap" -o "$images/frames_office1_up.png" >/dev/null
  measure+=(--room "$r")
fi

if has python; then
  echo "== python: examples/show_changes.py"
  PYTHONPATH="$build/python" /usr/bin/python3 examples/show_changes.py "$work/demo/office.cmap" \
    -o "$work/show" >/dev/null
  cp "$work/show/top_view.png" "$images/python_show_changes.png"
fi

if has architecture; then
  echo "== architecture: dot"
  dot -Tpng "$repo/docs/images/architecture.dot" -o "$images/architecture.png"
fi

# json_at FILE EXPR: the value at EXPR (Python subscripts, e.g. '["sessions"][43]["time"]') of a JSON file.
json_at() { python3 -c "import json, sys; print(json.load(open(sys.argv[1]))$2)" "$1"; }

if has weeks; then
  echo "== weeks: rhythm_eval, alerts_eval and colour_eval (true poses)"
  w="$work/weeks"
  mkdir -p "$w"
  # The rhythm: the combined model's prediction and the cost map at test session 43.
  "$cli" simulate --preset weeks --resolution-scale 0.25 -o "$w/sim" >/dev/null
  "$build/bench/rhythm_eval" --sim "$w/sim" --poses true --z-min 0.2 --robot-height 1.4 --lethal 0.7 \
    --save-map "$w/learn.cmap" >"$w/rhythm_eval.txt"
  at="$(json_at "$w/sim/scene.json" '["sessions"][43]["time"]')"
  "$cli" costmap "$w/learn.cmap" --at "$at" --lethal 0.7 --z-min 0.2 --z-max 1.4 --robot-radius 0.25 \
    -o "$w/cost.yaml" >/dev/null
  PYTHONPATH="$build/python" /usr/bin/python3 bench/rhythm_picture.py "$w/sim" "$w/learn.cmap" 43 "$w/cost.png" \
    "$images/weeks_predicted_vs_true.png" "$w/rhythm_picture.json"
  # The alerts of the night session 48 (03:35 on the Thursday of the test week).
  "$cli" simulate --preset weeks --resolution-scale 0.25 --rare-events -o "$w/rare" >/dev/null
  "$build/bench/alerts_eval" --sim "$w/rare" --poses true --map "$w/rare.cmap" >"$w/alerts_eval.txt"
  at="$(json_at "$w/rare/scene.json" '["sessions"][48]["time"]')"
  "$cli" alerts "$w/rare.cmap" --at "$at" --history-to 2012-03-26T00:00:00Z --top 5 -o "$w/night" >"$w/alerts.txt"
  cp "$w/night/alerts.png" "$images/alerts_night.png"
  # The colour model: the test sessions nearest 09:30 and 20:30.
  "$cli" simulate --preset weeks --resolution-scale 0.25 --lighting daylight --repaint -o "$w/colour_sim" >/dev/null
  "$build/bench/colour_eval" --weeks "$w/colour_sim" --out "$w/colour" >"$w/colour_eval.txt"
  mapfile -t hours < <(sed -n 's/^top views at session [0-9]* ([0-9-]*T\([0-9]*:[0-9]*\).*/\1/p' "$w/colour_eval.txt")
  ((${#hours[@]} == 2)) || { echo "colour_eval named ${#hours[@]} sessions for its top views, not 2" >&2; exit 1; }
  /usr/bin/python3 bench/colour_picture.py "$w/colour" "$images/colour_predicted_vs_true.png" "${hours[@]}"
  measure+=(--weeks "$w")
fi

if has floor66; then
  echo "== floor66: bench/temporal and the viewer"
  f="$work/floor66"
  mkdir -p "$f"
  "$cli" simulate --preset floor66 --resolution-scale 0.5 -o "$f/sim" >/dev/null
  "$build/bench/temporal" --sim "$f/sim" --plot "$images/floor66_storage.png" >"$f/temporal.txt"
  # The same 4D map as bench/temporal's (fast mode, the estimated poses), for the viewer.
  "$cli" build "$f/floor66.cmap" "$f"/sim/session_* --fast --json >"$f/build.json" 2>"$f/build.log"
  last="$(json_at "$f/build.json" '["added"][-1]["time"]')"
  "$cli" snapshot "$f/floor66.cmap" --at "$last" -o "$f/last.cmap" --json >"$f/last.json"
  shoot "$f/floor66.cmap" "$f/shot"
  cp "$f/shot-zoom.png" "$images/viewer_floor66_zoom.png"
  measure+=(--floor66 "$f")
fi

if has year; then
  echo "== year: bench/scale --plot-from"
  "$build/bench/scale" --plot-from "$repo/docs/images/year_nights.json" --plot "$images/year_nights.png"
  "$build/bench/scale" --plot-from "$repo/docs/images/year_one_floor_windows.json" \
    --plot "$images/year_one_floor_windows.png"
  "$build/bench/scale" --plot-from "$repo/docs/images/year_one_floor_windowed.json" \
    --plot "$images/year_one_floor_windowed.png"
  "$build/bench/scale" --plot-from "$repo/docs/images/year_windowed.json" --plot "$images/year_windowed.png"
  "$build/bench/scale" --plot-from "$repo/docs/images/year_site_windowed.json" \
    --plot "$images/year_site_windowed.png"
fi

figures="$repo/docs/images/figures.json"
if ((check)); then
  status=0
  python3 scripts/doc_figures.py check "$figures" "${measure[@]}" || status=1
  stale=()
  if [ "$images" != "$repo/docs/images" ]; then
    while read -r made; do
      name="$(basename "$made")"
      [[ "$name" == viewer_* ]] && continue
      cmp -s "$made" "$repo/docs/images/$name" || stale+=("$name")
    done < <(find "$images" -maxdepth 1 -name '*.png' -newer "$work/.started")
  fi
  if ((${#stale[@]})); then
    echo "make-doc-images.sh: docs/images differs from what the code draws now: ${stale[*]}" \
         "(scripts/make-doc-images.sh --only $groups remakes them)" >&2
    exit 1
  fi
  ((status == 0)) || exit 1
  echo "make-doc-images.sh: the pictures of $groups are those in docs/images"
else
  python3 scripts/doc_figures.py measure "$figures" "${measure[@]}"
  python3 scripts/doc_figures.py check "$figures"
fi
