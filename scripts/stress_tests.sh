#!/usr/bin/env bash
# Run the README's test command under CPU load, to show the suite does not depend on an idle
# machine:
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
#
# Options: --full N, --integration K, --busy B, --out DIR. Exit code 0 when every run passed.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FULL=3
INTEGRATION=10
BUSY=2
OUT=""
usage() { sed -n '2,14p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --full) FULL="$2"; shift 2 ;;
    --integration) INTEGRATION="$2"; shift 2 ;;
    --busy) BUSY="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "stress_tests.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
for n in "$FULL" "$INTEGRATION" "$BUSY"; do
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
trap 'stop_busy' EXIT
trap 'stop_busy; exit 130' INT TERM
for _ in $(seq 1 "$BUSY"); do
  python3 -c 'while True: pass' &
  busy_pids+=("$!")
done

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
record() {  # kind index log rc seconds
  local result
  result="$(grep -E '^(=+ )?[0-9]+ (passed|failed)' "$3" | tail -n 1 | tr -d '=' | xargs || true)"
  [[ -n "$result" ]] || result="(no pytest summary: see $3)"
  local load
  load="$(cut -d' ' -f1 /proc/loadavg)"
  printf '| %s | %s | %s | %s | %s | %s |\n' "$2" "$1" "$4" "$result" "$5" "$load" >> "$SUMMARY"
  echo "[stress] $1 run $2: exit $4, $result, $5 s, load $load" >&2
  [[ "$4" == 0 ]] || failures=$((failures + 1))
}

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
    exit 1
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
echo "failed runs: $failures of $((FULL + INTEGRATION))" >> "$SUMMARY"
cat "$SUMMARY"
[[ "$failures" == 0 ]]
