#!/usr/bin/env bash
# Proves that a change kept chronomap's behaviour: builds BASE (a git revision, default HEAD)
# and the working tree, runs the same commands with each, and compares every file they write
# and every JSON summary they print, byte for byte (timings left out).
#
#   scripts/compare-outputs.sh [BASE]
#   BASE_BIN=old/chronomap HEAD_BIN=new/chronomap scripts/compare-outputs.sh   (two builds at hand)
#
# The commands: integrate the 3DMatch recording (exact and fast), simulate the office preset,
# build a 4D map of it with registration (as the README recommends), diff and segment two of
# its times, and the demo. Work goes to build/compare/; exit 0 when everything is identical.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
base_rev="${1:-HEAD}"
data="${CHRONOMAP_DATA_DIR:-$root/../shared/data}"
work="$root/build/compare"
jobs="$(nproc)"
rm -rf "$work"
mkdir -p "$work"

base_bin="${BASE_BIN:-$work/base-build/apps/chronomap/chronomap}"
head_bin="${HEAD_BIN:-$work/head-build/apps/chronomap/chronomap}"
if [ -n "${BASE_BIN:-}" ] && [ -n "${HEAD_BIN:-}" ]; then
  base_bin="$(realpath "$BASE_BIN")"
  head_bin="$(realpath "$HEAD_BIN")"
  echo "comparing $base_bin and $head_bin"
else
  echo "building $base_rev and the working tree"
  git worktree add --detach "$work/base-src" "$base_rev" >/dev/null
  trap 'git worktree remove --force "$work/base-src" >/dev/null 2>&1 || true' EXIT
  for side in base head; do
    src="$root"
    [ "$side" = base ] && src="$work/base-src"
    cmake -S "$src" -B "$work/$side-build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCHRONOMAP_BUILD_TESTS=OFF >/dev/null
    cmake --build "$work/$side-build" -j"$jobs" --target chronomap_cli >/dev/null
  done
fi

# Runs every command with one build's binary in its own folder; JSON summaries to *.json.
run_all() {
  local bin="$1" out="$2"
  mkdir -p "$out"
  cd "$out"
  "$bin" integrate "$data/3dmatch/3dmatch" -o exact.cmap --json >integrate_exact.json
  "$bin" integrate "$data/3dmatch/3dmatch" -o fast.cmap --fast --json >integrate_fast.json
  "$bin" simulate --preset office --resolution-scale 0.5 -o sim --json >simulate.json
  "$bin" build office.cmap sim/session_* --fast --register --register-drift 20 --register-planar \
    --register-points --json >build.json
  local t0 t1
  t0="$(python3 -c 'import json;print(json.load(open("build.json"))["added"][0]["time"])')"
  t1="$(python3 -c 'import json;print(json.load(open("build.json"))["added"][1]["time"])')"
  "$bin" diff "office.cmap@$t0" "office.cmap@$t1" --mode band --neighbourhood 1 --min-shift 0.5 \
    --kept-surface 3 --dark-surface 2 -o d.cmap \
    --ply d.ply --json >diff.json
  "$bin" segment d.cmap --connectivity vertex --min-voxels 20 -o objects --json >segment.json
  "$bin" snapshot office.cmap --at "$t1" -o snap.png --json >snapshot.json
  "$bin" changes office.cmap --min 2 -o busy.ply --json >changes.json
  "$bin" stats office.cmap --plot storage.png --json >stats.json
  "$bin" demo -o demo --json >demo.json
  cd - >/dev/null
}
echo "running base"
run_all "$base_bin" "$work/base-out"
echo "running head"
run_all "$head_bin" "$work/head-out"

# Timings differ from run to run: drop every "seconds" key before comparing JSON.
python3 - "$work/base-out" "$work/head-out" <<'PY'
import json, pathlib, sys
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if k != "seconds"}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
base, head = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
files = sorted(p.relative_to(base) for p in base.rglob("*") if p.is_file())
others = sorted(p.relative_to(head) for p in head.rglob("*") if p.is_file())
bad = [f"only in one run: {p}" for p in sorted(set(files) ^ set(others))]
for rel in files:
    a, b = base / rel, head / rel
    if not b.exists():
        continue
    if rel.suffix == ".json" and rel.parent == pathlib.Path("."):
        same = strip(json.loads(a.read_text())) == strip(json.loads(b.read_text()))
    elif rel.name == "components.json":
        same = strip(json.loads(a.read_text())) == strip(json.loads(b.read_text()))
    else:
        same = a.read_bytes() == b.read_bytes()
    if not same:
        bad.append(f"differs: {rel}")
print(f"compared {len(files)} files")
for line in bad:
    print(line)
sys.exit(1 if bad else 0)
PY
echo "identical: every file and JSON summary (timings aside)"
