#!/usr/bin/env bash
# The --help of the project's shell scripts: the header comment of each SCRIPT given (the lines
# after #! up to the first line that is not a comment), then the exit-code table that every
# executable of the project shares (aero_dva/aero_dva/exits.py; Python 3 only, no setup needed).
#   bash scripts/usage.sh SCRIPT [SCRIPT ...]
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
for script in "$@"; do
  awk 'NR == 1 { next } /^#/ { sub(/^# ?/, ""); print; next } { exit }' "$script"
  echo
done
python3 "$REPO/aero_dva/aero_dva/exits.py" | fold -s -w 99 | sed 's/ *$//'
