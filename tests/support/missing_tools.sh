# Sourced by the ctest scripts that need tools beside the build (node, npm, Chromium):
#   skip_or_fail_missing NAME...   (the tools found missing; none: nothing happens)
# exits 77 (ctest's skip) naming them, except under CI=true, where scripts/install-deps.sh has
# installed them and a missing one is a failure (exit 1).
skip_or_fail_missing() {
  (($#)) || return 0
  if [ "${CI:-}" = true ]; then
    echo "missing: $* (scripts/install-deps.sh installs them)" >&2
    exit 1
  fi
  echo "skipped: $* not installed"
  exit 77
}
