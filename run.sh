#!/usr/bin/env bash
# Set up if needed (idempotent), then run the main job (see README.md for what it runs).
# ./run.sh --help prints what the main job does and the exit-code table; run_flight's own
# options: source scripts/env.sh && ros2 run aero_dva_sim run_flight --help.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  exec bash scripts/usage.sh "$0" scripts/main_job.sh
fi
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
exec bash scripts/main_job.sh "$@"
