#!/usr/bin/env bash
# `cmake --build "$@"`, whose failure ends with what explains it. A CI log keeps only its last
# few thousand characters, and a failed link prints its whole command line (tens of object
# paths) before the tool's own message: so on failure this prints again, last, the lines that
# name an error, each cut short, and the free disk space (a full disk fails a link or an
# archive step with nothing else to show for it).
#   scripts/build.sh --preset release -j 2 [--target NAME]
set -uo pipefail
cd "$(dirname "$0")/.."

log=$(mktemp "${TMPDIR:-/tmp}/touchstone-build.XXXXXX")
trap 'rm -f "$log"' EXIT
cmake --build "$@" 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
if ((status != 0)); then
  echo
  echo "build.sh: 'cmake --build $*' failed (exit $status). The lines that name an error:"
  grep -E -i "error|fatal|no space|cannot|undefined reference|killed" "$log" | grep -v "^: &&" |
    cut -c1-400 | tail -n 25 | sed 's/^/  /'
  echo "build.sh: free space where the build writes:"
  df -h . "${TMPDIR:-/tmp}" | sed 's/^/  /'
fi
exit "$status"
