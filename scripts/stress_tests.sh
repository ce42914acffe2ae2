#!/usr/bin/env bash
# Run the README's test command under CPU load, to show the suite does not depend on an idle
# machine, and runs side by side:
#   0. SIDE BY SIDE (skipped with --at-once 0): in a fresh clone, two setups started together
#      (as ./run.sh and ./test.sh would), both to exit 0 with one saying it waited, then a unit
#      test in the result; the README's schedule flight flown alone before the busy loops start
#      (the idle record), then ROUNDS rounds of AT_ONCE such flights started together beside
#      the busy loops: each must exit 0 with the idle record, in a bag of its own;
#   1. FULL times: a fresh clone of this checkout's HEAD (its own .venv and colcon build), then
#      `CI=true ./test.sh` in it, as CI runs it;
#   2. INTEGRATION times: `./test.sh tests/integration` in one more clone of that commit (set
#      up before the first run, outside its time);
# every run tests the commit that was HEAD at the start, whatever happens in this checkout
# meanwhile;
# each while BUSY CPU-bound loops run beside it. Prints one line per run and a summary table,
# and writes both to OUT/summary.md (default runs/stress_<UTC time>/); each run's pytest output
# goes next to it.
#
#   scripts/stress_tests.sh                       # 3 fresh-clone runs, 10 integration runs, 2 loops
#   scripts/stress_tests.sh --full 1 --integration 0 --busy 0     # one idle fresh-clone run
#   scripts/stress_tests.sh --full 0 --integration 0 --at-once 4  # flights side by side only
#
# Options: --full N, --integration K, --busy B, --at-once N (default 4; 0: skip part 0),
# --rounds R (default 2), --out DIR. Exit codes: 0 every run passed; 1 some run failed; 2 bad
# arguments; 130 interrupted.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FULL=3
INTEGRATION=10
BUSY=2
AT_ONCE=4
ROUNDS=2
OUT=""
usage() { bash "$REPO/scripts/usage.sh" "${BASH_SOURCE[0]}"; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --full) FULL="$2"; shift 2 ;;
    --integration) INTEGRATION="$2"; shift 2 ;;
    --busy) BUSY="$2"; shift 2 ;;
    --at-once) AT_ONCE="$2"; shift 2 ;;
    --rounds) ROUNDS="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "stress_tests.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
for n in "$FULL" "$INTEGRATION" "$BUSY" "$AT_ONCE" "$ROUNDS"; do
  [[ "$n" =~ ^[0-9]+$ ]] || { echo "stress_tests.sh: counts must be whole numbers, got '$n'" >&2; exit 2; }
done
OUT="${OUT:-$REPO/runs/stress_$(date -u +%Y%m%dT%H%M%SZ)}"
mkdir -p "$OUT"
SUMMARY="$OUT/summary.md"
COMMIT="$(git -C "$REPO" rev-parse HEAD)"
clone_commit() {  # DIR: a fresh clone of COMMIT in DIR/repo
  git clone -q --no-checkout "$REPO" "$1/repo"
  git -C "$1/repo" checkout -q --detach "$COMMIT"
}

# ---------------------------------------------------------------- the busy loops
busy_pids=()
stop_busy() {
  for pid in "${busy_pids[@]:-}"; do [[ -n "$pid" ]] && kill "$pid" 2>/dev/null || true; done
  busy_pids=()
}
start_busy() {
  for _ in $(seq 1 "$BUSY"); do
    python3 -c 'while True: pass' &
    busy_pids+=("$!")
  done
}
side_clone=""
trap 'stop_busy; [[ -z "$side_clone" ]] || rm -rf "$side_clone"' EXIT
trap 'stop_busy; exit 130' INT TERM

{
  echo "# Test suite under load"
  echo
  echo "$(date -u +%Y-%m-%dT%H:%M:%SZ), commit ${COMMIT:0:7}, $(nproc) cores,"
  echo "$BUSY CPU-bound loops beside each run."
  echo
  echo "| run | kind | exit | result | wall s | load (1 min) at the end |"
  echo "|---|---|---|---|---|---|"
} > "$SUMMARY"

failures=0
runs=0
record() {  # kind index log rc seconds
  local result
  result="$(grep -E '^(=+ )?[0-9]+ (passed|failed)' "$3" | tail -n 1 | tr -d '=' | xargs || true)"
  [[ -n "$result" ]] || result="(no pytest summary: see $3)"
  local load
  load="$(cut -d' ' -f1 /proc/loadavg)"
  printf '| %s | %s | %s | %s | %s | %s |\n' "$2" "$1" "$4" "$result" "$5" "$load" >> "$SUMMARY"
  echo "[stress] $1 run $2: exit $4, $result, $5 s, load $load" >&2
  runs=$((runs + 1))
  [[ "$4" == 0 ]] || failures=$((failures + 1))
}
note() {  # kind index rc result seconds: a row without a pytest log
  local load
  load="$(cut -d' ' -f1 /proc/loadavg)"
  printf '| %s | %s | %s | %s | %s | %s |\n' "$2" "$1" "$3" "$4" "$5" "$load" >> "$SUMMARY"
  echo "[stress] $1 $2: exit $3, $4, $5 s, load $load" >&2
  runs=$((runs + 1))
  [[ "$3" == 0 ]] || failures=$((failures + 1))
}

# ---------------------------------------------------------------- 0. side by side
# The record of a flight: what lockstep makes the same whatever the load (docs/reliability.md).
RECORD_KEYS="divergence_ratio leading_edge_rms mean_damping commands_received commands_recorded blocks_startup blocks_fallback data_published data_missing"
record_of() {  # summary.json -> the record, one line
  python3 -c 'import json, sys; d = json.load(open(sys.argv[1])); print(" ".join(repr(d.get(k)) for k in sys.argv[2].split()))' "$1" "$RECORD_KEYS"
}
if [[ "$AT_ONCE" -gt 0 ]]; then
  side_clone="$(mktemp -d "${TMPDIR:-/tmp}/dva-stress-side.XXXXXX")"
  clone_commit "$side_clone"
  repo="$side_clone/repo"
  start=$SECONDS
  (cd "$repo" && bash scripts/setup.sh) > "$OUT/setup_a.log" 2>&1 &
  setup_a=$!
  (cd "$repo" && bash scripts/setup.sh) > "$OUT/setup_b.log" 2>&1 &
  setup_b=$!
  set +e
  wait "$setup_a"; rc_a=$?
  wait "$setup_b"; rc_b=$?
  (cd "$repo" && ./test.sh tests/unit/project -q -p no:cacheprovider) > "$OUT/setup_check.log" 2>&1
  rc_check=$?
  set -e
  waited="$(cat "$OUT/setup_a.log" "$OUT/setup_b.log" | grep -c 'waiting for it to finish' || true)"
  rc=$(( rc_a || rc_b || rc_check || waited != 1 ))
  note "two setups of one fresh clone at once" 1 "$rc" "setups exit $rc_a and $rc_b, $waited waited, then tests/unit/project exit $rc_check" "$((SECONDS - start))"
  if [[ "$rc_a" == 0 && "$rc_b" == 0 ]]; then
    flights="$OUT/flights"
    mkdir -p "$flights"
    (cd "$repo" && source scripts/env.sh && dva control schedule --out "$flights/schedule.json" > /dev/null)
    fly() {  # NAME: the README's schedule flight in the clone, default bag name
      (cd "$repo" && source scripts/env.sh && ros2 run aero_dva_sim run_flight \
        --controller schedule --schedule "$flights/schedule.json" --json) \
        > "$flights/$1.json" 2> "$flights/$1.err"
    }
    set +e
    fly idle
    rc=$?
    set -e
    idle="$(record_of "$flights/idle.json" 2>/dev/null || echo none)"
    note "one flight, idle (the idle record)" 0 "$rc" "$idle" 0
    start_busy
    for round in $(seq 1 "$ROUNDS"); do
      start=$SECONDS
      pids=()
      for i in $(seq 1 "$AT_ONCE"); do fly "round${round}_$i" & pids+=("$!"); done
      codes=()
      for pid in "${pids[@]}"; do set +e; wait "$pid"; codes+=("$?"); set -e; done
      same=0
      bags=()
      for i in $(seq 1 "$AT_ONCE"); do
        [[ "$(record_of "$flights/round${round}_$i.json" 2>/dev/null || echo x)" == "$idle" ]] && same=$((same + 1))
        bags+=("$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["bag"])' "$flights/round${round}_$i.json" 2>/dev/null || echo none)")
      done
      distinct="$(printf '%s\n' "${bags[@]}" | sort -u | grep -vc '^none$' || true)"
      ok=$(( ${#codes[@]} == AT_ONCE ))
      for c in "${codes[@]}"; do [[ "$c" == 0 ]] || ok=0; done
      rc=$(( !(ok && same == AT_ONCE && distinct == AT_ONCE) ))
      note "$AT_ONCE flights started together" "$round" "$rc" "exit codes ${codes[*]}; $same of $AT_ONCE with the idle record; $distinct distinct bags" "$((SECONDS - start))"
    done
    stop_busy
  fi
  rm -rf "$side_clone"
  side_clone=""
fi
start_busy

# ---------------------------------------------------------------- fresh clones, whole suite
for i in $(seq 1 "$FULL"); do
  clone="$(mktemp -d "${TMPDIR:-/tmp}/dva-stress-clone.XXXXXX")"
  log="$OUT/full_$i.log"
  clone_commit "$clone"
  start=$SECONDS
  set +e
  (cd "$clone/repo" && CI=true ./test.sh -p no:cacheprovider) > "$log" 2>&1
  rc=$?
  set -e
  record "fresh clone, ./test.sh" "$i" "$log" "$rc" "$((SECONDS - start))"
  rm -rf "$clone"
done

# ---------------------------------------------------------------- integration tests, K times
if [[ "$INTEGRATION" -gt 0 ]]; then
  clone="$(mktemp -d "${TMPDIR:-/tmp}/dva-stress-clone.XXXXXX")"
  clone_commit "$clone"
  if ! (cd "$clone/repo" && bash scripts/setup.sh) > "$OUT/integration_setup.log" 2>&1; then
    echo "[stress] setting up the integration clone failed: see $OUT/integration_setup.log" >&2
    rm -rf "$clone"
    exit 3
  fi
  for i in $(seq 1 "$INTEGRATION"); do
    log="$OUT/integration_$i.log"
    start=$SECONDS
    set +e
    (cd "$clone/repo" && ./test.sh tests/integration -p no:cacheprovider) > "$log" 2>&1
    rc=$?
    set -e
    record "./test.sh tests/integration" "$i" "$log" "$rc" "$((SECONDS - start))"
  done
  rm -rf "$clone"
fi

stop_busy
echo >> "$SUMMARY"
echo "failed runs: $failures of $runs" >> "$SUMMARY"
cat "$SUMMARY"
[[ "$failures" == 0 ]]
