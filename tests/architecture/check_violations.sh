#!/usr/bin/env bash
# Shows that scripts/check-architecture.sh fails on each kind of violation it names: a copy of
# the tree's headers, sources and commands gets one violation at a time, and the check must fail
# naming it; the untouched copy must pass.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
fresh() {
  rm -rf "$work/tree"
  mkdir -p "$work/tree/apps"
  cp -r "$root/include" "$root/src" "$work/tree/"
  cp -r "$root/apps/chronomap" "$work/tree/apps/"
  mkdir -p "$work/tree/python"
  cp -r "$root/python/src" "$work/tree/python/" 2>/dev/null || true
}
expect_failure() {
  local what="$1" needle="$2"
  if out="$("$root/scripts/check-architecture.sh" "$work/tree" 2>&1)"; then
    echo "FAIL: the check passed with $what"
    exit 1
  fi
  if ! grep -qF "$needle" <<<"$out"; then
    echo "FAIL: the check failed with $what but did not say '$needle':"
    echo "$out"
    exit 1
  fi
  echo "ok: $what"
}
fresh
out="$("$root/scripts/check-architecture.sh" "$work/tree" 2>&1)" || { echo "FAIL: the untouched tree fails:"; echo "$out"; exit 1; }
echo "ok: the untouched tree passes"

echo '#include "chronomap/ingest/ros/rosbag.h"' >>"$work/tree/src/view/tour.cpp"
expect_failure "view including ingest/ros" "view may not include ingest/ros"

fresh
echo '#include "chronomap/store/cmap.h"' >>"$work/tree/src/ingest/png.cpp"
expect_failure "ingest including store" "ingest may not include store"

fresh
mkdir -p "$work/tree/src/newmodule"
touch "$work/tree/src/newmodule/a.cpp"
expect_failure "a module missing from the table" "module 'newmodule' is not in the table"

fresh
{
  echo 'int tooLong() {'
  for i in $(seq 151); do echo "  int v$i = $i;"; done
  echo '  return 0;'
  echo '}'
} >>"$work/tree/src/core/key.cpp"
expect_failure "a library function of 152 lines" "library functions longer than 150 lines"

fresh
{
  echo 'int tooLong(int a,'
  echo '            int b) {'
  for i in $(seq 61); do echo "  a += $i;"; done
  echo '  return a + b;'
  echo '}'
} >>"$work/tree/apps/chronomap/main.cpp"
expect_failure "a command function of 62 lines" "functions of apps/chronomap longer than 60 lines"
