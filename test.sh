#!/usr/bin/env bash
# Set up if needed (idempotent), then run every test: lint, unit and ROS 2 integration tests.
# Extra arguments go to pytest, e.g. ./test.sh tests/unit -k isolator
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
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
exec python -m pytest -n "${DVA_TEST_WORKERS:-2}" --dist worksteal "$@"
