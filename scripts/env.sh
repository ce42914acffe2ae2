# Source this file (bash) for a shell with the project's ROS 2 environment:
#   source scripts/env.sh
# It activates .venv, makes the ROS 2 Jazzy wheels (or the sourced system ROS 2) the underlay
# and the colcon-built ros_ws the overlay, so `ros2 run aero_dva_sim <exe>` and the nodes work.
# Run scripts/setup.sh first (the two README commands do).
_dva_repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
_dva_venv="${DVA_VENV:-$_dva_repo/.venv}"
if [[ ! -f "$_dva_venv/.dva-venv-stamp" || ! -f "$_dva_repo/ros_ws/install/local_setup.bash" ]]; then
  echo "env.sh: the project is not set up yet; run scripts/setup.sh first" >&2
  return 1 2>/dev/null || exit 1
fi
export VIRTUAL_ENV="$_dva_venv"
export PATH="$_dva_venv/bin:$PATH"
if [[ -z "${ROS_DISTRO:-}" ]]; then
  # ROS 2 Jazzy from the PyPI wheels: the venv is the underlay prefix.
  export AMENT_PREFIX_PATH="$_dva_venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  export CMAKE_PREFIX_PATH="$_dva_venv${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
  export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
fi
# colcon's setup scripts read unset variables: relax `set -u` while sourcing them.
_dva_nounset=0; [[ $- == *u* ]] && _dva_nounset=1; set +u
# shellcheck disable=SC1091
COLCON_CURRENT_PREFIX="$_dva_repo/ros_ws/install" source "$_dva_repo/ros_ws/install/local_setup.bash"
(( _dva_nounset )) && set -u
export DVA_REPO="$_dva_repo"
# Python writes the bytecode of what it imports (into .venv and the gitignored __pycache__
# folders), once: the nodes, `dva` commands and test workers import the same modules, and
# with PYTHONDONTWRITEBYTECODE set (as some images do) every process compiled them again.
unset PYTHONDONTWRITEBYTECODE
unset _dva_repo _dva_venv _dva_nounset
