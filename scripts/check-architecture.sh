#!/usr/bin/env bash
# Checks the module graph of docs/architecture.md against the code: every include of a
# chronomap header from a module's headers and sources names that module or one the table
# below allows, and no function of the command line (apps/chronomap) is longer than 60 lines
# (commands parse, call the library once and print; workflows live in pipeline/).
set -euo pipefail
cd "$(dirname "$0")/.."

# Module: the modules it may include besides itself (docs/architecture.md, "Layers").
declare -A allowed=(
  [core]=""
  [octree]="core"
  [temporal]="core octree"
  [integrate]="core octree"
  [analysis]="core octree temporal"
  [align]="core octree temporal integrate"
  [io]="core octree temporal analysis"
  [render]="core octree temporal analysis"
  [sim]="core octree analysis io"
  [pipeline]="core octree temporal integrate analysis align io render sim view"
  [view]="core octree temporal analysis io"
)

failures=0
for module in "${!allowed[@]}"; do
  for dir in "include/chronomap/$module" "src/$module"; do
    [ -d "$dir" ] || continue
    while IFS=: read -r file line include; do
      target="${include#*chronomap/}"
      target="${target%%/*}"
      [ "$target" = "$module" ] && continue
      if [[ " ${allowed[$module]} " != *" $target "* ]]; then
        echo "$file:$line: $module may not include $target ($include)"
        failures=$((failures + 1))
      fi
    done < <(grep -rnoE '#include "chronomap/[a-z_]+/[a-z_]+\.h"' "$dir" || true)
  done
done
# Every module folder is in the table.
for dir in include/chronomap/*/ src/*/; do
  module="$(basename "$dir")"
  if [ -z "${allowed[$module]+set}" ]; then
    echo "$dir: module '$module' is not in the table of scripts/check-architecture.sh and docs/architecture.md"
    failures=$((failures + 1))
  fi
done

# The Python bindings (python/src) sit on top like the command line: they may include any
# module, but only through its public headers, and no module may include them.
while IFS=: read -r file line include; do
  header="include/${include#\#include \"}"
  header="${header%\"}"
  if [ ! -f "$header" ]; then
    echo "$file:$line: the bindings include $include, which is not a public header of a module"
    failures=$((failures + 1))
  fi
done < <(grep -rnoE '#include "chronomap/[a-z_]+/[a-z_]+\.h"' python/src 2>/dev/null || true)
if grep -rnE '#include "(python|bindings)' include src 2>/dev/null; then
  echo "a module includes the Python bindings"
  failures=$((failures + 1))
fi

# Functions of the command line: from a line that opens a body at column 0 to its closing brace.
long="$(awk 'FNR == 1 { start = 0 }
  /^[A-Za-z].*\) (const )?\{$/ || /^[A-Za-z].*\) -> .*\{$/ { start = FNR; name = $0; next }
  /^}/ && start { if (FNR - start - 1 > 60) printf "%s:%d: %d lines: %s\n", FILENAME, start, FNR - start - 1, name; start = 0 }' \
  apps/chronomap/*.cpp)"
if [ -n "$long" ]; then
  echo "functions of apps/chronomap longer than 60 lines (move the workflow into pipeline/):"
  echo "$long"
  failures=$((failures + 1))
fi

if [ "$failures" -gt 0 ]; then
  echo "architecture check: $failures problem(s)"
  exit 1
fi
echo "architecture check: the includes follow the module table; no command function over 60 lines"
