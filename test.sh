#!/usr/bin/env bash
# Set up if needed (idempotent), then run every test: lint, unit and ROS 2 integration tests.
# Extra arguments go to pytest, e.g. ./test.sh tests/unit -k isolator (pytest's own options:
# .venv/bin/python -m pytest --help); ./test.sh --help prints this and the exit-code table.
# Exit codes (every executable's, aero_dva/aero_dva/exits.py): 0 every test passed; 1 tests
# ran and some failed; 2 bad input (pytest's usage errors, or no test selected); 3 the setup
# or pytest itself failed; 130 interrupted (SIGINT or SIGTERM).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then exec bash scripts/usage.sh "$0"; fi
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
# One BLAS thread per process: the two workers already keep both cores busy, and OpenBLAS's own
# threads beside them spin for CPU (one flight analysis beside a loaded suite: 25.9 s of CPU
# with two BLAS threads, 14.6 s with one). The nodes the integration tests start inherit it.
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
# Two worker processes (pytest-xdist); an idle worker takes tests from the other's queue
# (worksteal), so a slow file does not leave one core idle at the end (a module fixture may
# then run on both workers). DVA_TEST_WORKERS=0 runs every test in this process.
# pytest runs as a child this script waits for, so that a SIGTERM to the script stops it at
# once as Ctrl-C does (SIGINT: pytest ends its tests and says what ran); a Ctrl-C reaches both
# from the terminal. Its SIGINT is restored (a background child's is ignored) and its stdin
# stays the terminal's (pdb).
exec 3<&0
(trap - INT; exec python -m pytest -n "${DVA_TEST_WORKERS:-2}" --dist worksteal "$@" <&3) &
pytest_pid=$!
trap 'wait "$pytest_pid"; exit 130' INT
trap 'kill -INT "$pytest_pid" 2>/dev/null; wait "$pytest_pid"; exit 130' TERM
set +e
wait "$pytest_pid"
code=$?
set -e
# pytest's own codes: 0 passed, 1 failed, 2 interrupted, 3 internal error, 4 usage, 5 no tests
case "$code" in
  0|1|3) exit "$code" ;;
  2) exit 130 ;;
  4|5) exit 2 ;;
  *) exit 3 ;;
esac
