#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) and runs each for SECONDS (default 60),
# as many at once as there are cores.
# Seeds: small files made by chronomap's own writers, plus small real files from the data folder.
# A crash, or an input that takes more than 10 s (a hang), leaves its input as build/fuzz/artifacts/<target>/crash-*; turn it into a regression
# test under tests/<module> (the reader's folder) before fixing it. Memory bombs are findings too: a run may hold 2 GiB
# (-rss_limit_mb) and no single allocation may reach 1 GiB (-malloc_limit_mb) from an input of at
# most 64 KiB, which no reader's bound allows (docs/reliability.md, "Limits").
# Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
scripts/install-deps.sh
if ! command -v clang++ >/dev/null || [ ! -d /usr/lib/llvm-14/lib/clang ]; then
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends clang libclang-rt-dev >/dev/null
fi
cmake --preset fuzz >/dev/null
# Only the fuzz targets and the modules they link (not the command line or the simulator).
cmake --build --preset fuzz -j"$(nproc)" --target fuzz_cmap fuzz_pcd fuzz_ply fuzz_xyz fuzz_png fuzz_text fuzz_model fuzz_view fuzz_bag \
  fuzz_rosmsg fuzz_mcap fuzz_cdr fuzz_db3 fuzz_make_seeds
bin=build/fuzz/fuzz
data="${CHRONOMAP_DATA_DIR:-../shared/data}"
seeds=build/fuzz/seeds
rm -rf "$seeds"
"$bin/fuzz_make_seeds" "$seeds"
copy_seed() { [ -f "$1" ] && cp "$1" "$seeds/$2/" || true; }
copy_seed "$data/rgbd-formats/TUM_depth.png" png
copy_seed "$data/3dmatch/3dmatch/seq-01/frame-000000.depth.png" png
copy_seed "$data/pcl-kinect/grabber_sequences/pcd/frame_20121214T142255.814212.pcd" pcd
# The viewer's API: one request of each kind (fuzz_view reads "PATH?QUERY").
mkdir -p "$seeds/view"
printf '/api/snapshot?session=2&budget=10&level=1&region=32768,32768,32768,32770,32770,32770' >"$seeds/view/snapshot"
printf '/api/snapshot?t=1970-01-01T00:25:00Z' >"$seeds/view/snapshot_t"
printf '/api/diff?from=0&to=2&min_voxels=1' >"$seeds/view/diff"
printf '/api/history?key=32768,32768,32768&level=2' >"$seeds/view/history"
printf '/api/map' >"$seeds/view/map"
# ROS 1 bags written by Debian's python3-rosbag, as the tests write them.
/usr/bin/python3 tests/ingest/ros/make_ros1_bags.py --seeds "$seeds/bag"
# ROS 2 bags written by npm's @mcap/core (tests/ingest/ros/ros2_writer, as the tests write them); the CDR
# target's seeds are their messages, each behind the byte that picks its decoder.
writer=build/fuzz/ros2_writer
mkdir -p "$writer"
cp tests/ingest/ros/ros2_writer/package.json tests/ingest/ros/ros2_writer/package-lock.json tests/ingest/ros/ros2_writer/make_ros2_bags.mjs "$writer/"
[ -d "$writer/node_modules/@mcap/core" ] || (cd "$writer" && npm ci --no-audit --no-fund >/dev/null)
node "$writer/make_ros2_bags.mjs" --seeds "$seeds/mcap" "$seeds/cdr"
# SQLite bags (rosbag2's .db3) of the same messages, written as the tests write theirs.
"$bin/fuzz_make_seeds" --db3 "$seeds/mcap" "$seeds/db3"
summary=build/fuzz/summary.txt
: >"$summary"
# One target per core at a time; each writes its own log and result line.
fuzz_one() {
  local target="$1" corpus="build/fuzz/corpus/$1" artifacts="build/fuzz/artifacts/$1" log="build/fuzz/$1.log" result runs
  mkdir -p "$corpus" "$artifacts"
  if "$bin/fuzz_$target" "$corpus" "$seeds/$target" -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
       -timeout=10 -artifact_prefix="$artifacts/" -print_final_stats=1 >"$log" 2>&1; then
    result=ok
  else
    result=CRASH
  fi
  runs=$(grep -m1 -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  printf '%-5s %-6s %10s executions in %ss\n' "$target" "$result" "$runs" "$seconds" >"build/fuzz/$target.result"
}
jobs="$(nproc)"
rm -f build/fuzz/*.result
targets=(cmap pcd ply xyz png text model view bag rosmsg mcap cdr db3)
for target in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
  fuzz_one "$target" &
done
wait
for target in "${targets[@]}"; do
  cat "build/fuzz/$target.result" | tee -a "$summary"
  grep -q ' ok ' "build/fuzz/$target.result" || tail -30 "build/fuzz/$target.log"
done
status=0
grep -q ' CRASH ' "$summary" && status=1
echo "fuzz: $(grep -c ' ok ' "$summary") passed, $(grep -c ' CRASH ' "$summary") failed"
exit $status
