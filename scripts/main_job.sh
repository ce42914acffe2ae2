#!/usr/bin/env bash
# The main job (run by ./run.sh after setup, in the project's ROS 2 environment):
#  1. fit the airspeed schedule c2 = a0 + a1 U (Zhang (2006) eq. 7.1) to the c2 that minimises the
#     exact stationary leading-edge RMS of the default (chapter-6) wing with its Maxwell DVA;
#  2. fly the study's ramp (0.8 -> 1.2 U_cr in 30 s, 1 kN white-noise aileron force) through the
#     node graph -- simulator, airspeed_controller, mcap_recorder as separate processes over DDS
#     on sim time -- and print the summary read back from the recorded MCAP bag.
# Extra arguments go to run_flight (see: ros2 run aero_dva_sim run_flight --help). Several
# main jobs may run at once: each writes its own schedule file and bag (runs/main_<UTC time>,
# or the first free runs/main_<UTC time>_N). Exit codes: run_flight's (0 done, 1 flown but not
# counted as controlled, 2 bad input, 3 failed, 130 interrupted).
set -euo pipefail
stamp="$(date -u +%Y%m%dT%H%M%SZ)"
mkdir -p runs
schedule="$(mktemp "runs/schedule_${stamp}_XXXXXX" --suffix .json)"
echo "[main] fitting the airspeed schedule (eq. 7.1) for the chapter-6 wing" >&2
# (its progress bar off; an error of it still says its one line, and its code ends the job)
TQDM_DISABLE=1 dva control schedule --out "$schedule" 2>&1 | sed 's/^/[main]   /' >&2
name=(--name main)
for arg in "$@"; do [[ "$arg" == --output || "$arg" == --output=* ]] && name=(); done
echo "[main] flying the ramp through the node graph" >&2
exec ros2 run aero_dva_sim run_flight --controller schedule --schedule "$schedule" "${name[@]}" "$@"
