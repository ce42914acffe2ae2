#!/usr/bin/env bash
# Set up if needed (idempotent), then run the main job (see README.md for what it runs).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
exec bash scripts/main_job.sh "$@"
