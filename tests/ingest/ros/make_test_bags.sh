#!/usr/bin/env bash
# The recordings the bag tests read, made once per build and shared by the ROS 1 and ROS 2
# suites: a simulated TUM session (the tiny preset at 160 x 120), ROS 1 bags written from it by
# Debian's python3-rosbag (tests/ingest/ros/make_ros1_bags.py, with the tiny seed bags), and MCAP bags
# written by npm's @mcap/core (tests/ingest/ros/ros2_writer, installed with npm ci into WRITER_DIR).
#
#   make_test_bags.sh CLI SOURCE_DIR WRITER_DIR OUT
#
# OUT/sim/session_00 is the TUM folder, OUT/bags the bags. A writer that fails leaves its error
# in OUT/ros1.error or OUT/ros2.error (the suite that needs it fails under CI=true, skips
# elsewhere); only a failing simulation fails the script. OUT/stamp names what the recordings
# were made with (the command-line tool's size and time, the writers' checksums): when it still
# matches, nothing is made again, so every test may call this and only the first one pays.
set -euo pipefail
cli="$1" src="$2" writer="$3" out="$4"
mkdir -p "$(dirname "$out")"
exec 9>"$out.lock"
flock 9
stamp="$(stat -c '%s %Y' "$cli"; cd "$src/tests/ingest/ros" &&
  md5sum make_test_bags.sh make_ros1_bags.py ros2_writer/make_ros2_bags.mjs ros2_writer/package-lock.json)"
if [ -f "$out/stamp" ] && [ "$(cat "$out/stamp")" = "$stamp" ]; then exit 0; fi
new="$out.new"
rm -rf "$new" "$out"
mkdir -p "$new/bags"
"$cli" simulate --preset tiny --sessions 1 --resolution-scale 0.25 -o "$new/sim" >/dev/null
tum="$new/sim/session_00"
# ROS 1: Debian's interpreter, which has python3-rosbag (the first python3 on PATH may not).
if ! { /usr/bin/python3 "$src/tests/ingest/ros/make_ros1_bags.py" "$tum" "$new/bags" &&
  /usr/bin/python3 "$src/tests/ingest/ros/make_ros1_bags.py" --seeds "$new/bags/tiny"; } 2>"$new/ros1.error"; then
  echo "make_ros1_bags.py failed: $(tail -3 "$new/ros1.error")" >&2
else
  rm "$new/ros1.error"
fi
# ROS 2: the npm writers from the committed lock.
mkdir -p "$writer"
for f in package.json package-lock.json make_ros2_bags.mjs; do cp "$src/tests/ingest/ros/ros2_writer/$f" "$writer/$f"; done
if ! { { [ -d "$writer/node_modules/@mcap/core" ] || (cd "$writer" && npm ci --no-audit --no-fund >/dev/null); } &&
  node "$writer/make_ros2_bags.mjs" "$tum" "$new/bags"; } 2>"$new/ros2.error"; then
  echo "make_ros2_bags.mjs failed: $(tail -3 "$new/ros2.error")" >&2
else
  rm "$new/ros2.error"
fi
printf '%s\n' "$stamp" >"$new/stamp"
mv "$new" "$out"
