#!/usr/bin/env bash
# Set up if needed (idempotent), then run every test: lint, unit and ROS 2 integration tests.
# Extra arguments go to pytest, e.g. ./test.sh tests/unit -k isolator
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
exec python -m pytest "$@"
