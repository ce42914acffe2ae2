#!/usr/bin/env bash
# Set up if needed (idempotent), then run every test: lint, unit and ROS 2 integration tests.
# Extra arguments go to pytest, e.g. ./test.sh tests/unit -k isolator
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
# Two worker processes (pytest-xdist), one test file per worker at a time, so module fixtures
# run once; DVA_TEST_WORKERS=0 runs every test in this process.
exec python -m pytest -n "${DVA_TEST_WORKERS:-2}" --dist loadfile "$@"
