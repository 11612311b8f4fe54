#!/usr/bin/env bash
# Checks the module graph of docs/architecture.md against the code: every include of a
# chronomap header from a module's headers and sources names that module or one the table
# below allows; no library function (src/, include/) is longer than 150 lines and no function
# of the command line (apps/chronomap) longer than 60 (commands parse, call the library once and
# print; workflows live in pipeline/).
#
#   scripts/check-architecture.sh [ROOT]   (ROOT: the tree to check, default this checkout)
set -euo pipefail
cd "${1:-$(dirname "$0")/..}"

# Module: the modules it may include besides itself (docs/architecture.md, "Layers").
declare -A allowed=(
  [core]=""
  [octree]="core"
  [temporal]="core octree"
  [integrate]="core octree"
  [analysis]="core octree temporal"
  [align]="core octree temporal integrate"
  [ingest]="core"
  [ingest/ros]="core ingest"
  [store]="core octree temporal analysis"
  [export]="core octree temporal analysis ingest"
  [render]="core octree temporal analysis"
  [sim]="core octree analysis ingest store"
  [view]="core octree temporal analysis"
  [pipeline]="core octree temporal integrate analysis align ingest ingest/ros store export render sim view"
)

# The module an include names: its folder under chronomap/ (ingest/ros is a module of its own).
module_of() {
  local path="${1#*chronomap/}"
  path="${path%\"}"
  case "$path" in
    ingest/ros/*) echo "ingest/ros" ;;
    *) echo "${path%%/*}" ;;
  esac
}

failures=0
for module in "${!allowed[@]}"; do
  for dir in "include/chronomap/$module" "src/$module"; do
    [ -d "$dir" ] || continue
    # A module's folder holds only its own files: ingest/ros is checked as its own module.
    prune=()
    [ "$module" = ingest ] && prune=(-path "$dir/ros" -prune -o)
    while IFS=: read -r file line include; do
      target="$(module_of "$include")"
      [ "$target" = "$module" ] && continue
      if [[ " ${allowed[$module]} " != *" $target "* ]]; then
        echo "$file:$line: $module may not include $target ($include)"
        failures=$((failures + 1))
      fi
    done < <(find "$dir" "${prune[@]}" -type f \( -name '*.h' -o -name '*.cpp' \) -print0 |
             xargs -0 -r grep -HnoE '#include "chronomap/[a-z_]+(/[a-z_]+)?/[a-z_]+\.h"' || true)
  done
done
# Every module folder is in the table.
for dir in include/chronomap/*/ src/*/ include/chronomap/*/*/ src/*/*/; do
  [ -d "$dir" ] || continue
  module="${dir#include/chronomap/}"
  module="${module#src/}"
  module="${module%/}"
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
done < <(grep -rnoE '#include "chronomap/[a-z_]+(/[a-z_]+)?/[a-z_]+\.h"' python/src 2>/dev/null || true)
if grep -rnE '#include "(python|bindings)' include src 2>/dev/null; then
  echo "a module includes the Python bindings"
  failures=$((failures + 1))
fi

# Long functions: from a declaration that starts at column 0 (its signature may span up to 8
# lines) to the closing brace at column 0 of its body. Member functions defined inside a class
# body are not measured; every long one today is defined at column 0.
long_functions() {
  local limit="$1"
  shift
  awk -v limit="$limit" '
    FNR == 1 { cand = 0; start = 0 }
    start == 0 && /^[A-Za-z]/ && !/^(namespace|struct|class|enum|union|extern|template|using|typedef|static_assert)/ &&
      !/[;}][ ]*$/ { cand = FNR; name = $0 }
    start == 0 && cand && /\{[ ]*$/ && FNR - cand < 8 { start = FNR; next }
    start == 0 && cand && /[;}][ ]*$/ { cand = 0 }
    /^}/ && start { n = FNR - start - 1; if (n > limit) printf "%s:%d: %d lines: %s\n", FILENAME, cand, n, name
                    start = 0; cand = 0 }' "$@"
}
long="$(long_functions 60 apps/chronomap/*.cpp)"
if [ -n "$long" ]; then
  echo "functions of apps/chronomap longer than 60 lines (move the workflow into pipeline/):"
  echo "$long"
  failures=$((failures + 1))
fi
mapfile -d '' library < <(find src include -type f \( -name '*.cpp' -o -name '*.h' \) -print0)
long="$(long_functions 150 "${library[@]}")"
if [ -n "$long" ]; then
  echo "library functions longer than 150 lines (split them; docs/architecture.md):"
  echo "$long"
  failures=$((failures + 1))
fi

if [ "$failures" -gt 0 ]; then
  echo "architecture check: $failures problem(s)"
  exit 1
fi
echo "architecture check: the includes follow the module table; no library function over 150 lines, no command" \
  "function over 60"
