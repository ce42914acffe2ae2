"""What starting each executable imports (structural checks, not timings; the times are
bench/bench_graph_speed.py's, docs/performance.md): ``--help`` answers from the node's table before
ROS, numpy or the node's module are imported, and a node module imports neither scipy nor
numba, which only a configuration that asks for them loads (the flutter search's U_cr is kept
on disk, the compiled loops load for ``stepping:=compiled`` or a per-sample law)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("dva_msgs.msg", reason="needs the built workspace (source scripts/env.sh)")

from ament_index_python.packages import get_package_prefix  # noqa: E402

from .test_node_help import ENTRY_POINTS  # noqa: E402

HEAVY = {"rclpy", "numpy", "scipy", "numba"}
NODE_MODULES = ("aero_dva_sim.simulator_node", "aero_dva_sim.mcap_recorder_node",
                "aero_dva_sim.bag_player_node", "dva_controller.controller_node",
                "dva_controller.spectrum_node", "dva_controller.switching_controller_node")
REPORT = ("\nprint(json.dumps(sorted({m.split('.')[0] for m in sys.modules})), file=sys.stderr)")


def _modules(code: str) -> set[str]:
    result = subprocess.run([sys.executable, "-c", "import json, sys\n" + code + REPORT],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return set(json.loads(result.stderr.strip().splitlines()[-1]))


@pytest.mark.parametrize(("package", "executable", "module"), ENTRY_POINTS,
                         ids=[e for _, e, _ in ENTRY_POINTS])
def test_help_imports_neither_ros_nor_numpy(package, executable, module):
    path = str(Path(get_package_prefix(package)) / "lib" / package / executable)
    code = (f"import runpy\nsys.argv = [{path!r}, '--help']\ntry:\n"
            f"    runpy.run_path({path!r}, run_name='__main__')\nexcept SystemExit:\n    pass")
    assert not _modules(code) & HEAVY


@pytest.mark.parametrize("module", NODE_MODULES)
def test_a_node_module_imports_neither_scipy_nor_numba(module):
    imported = _modules(f"import {module}")
    assert "rclpy" in imported  # (the check imports what a node imports)
    assert not imported & {"scipy", "numba"}


def test_the_simulators_set_up_of_a_flight_without_per_sample_laws_loads_neither():
    # The simulator's runtime as its node builds it for a schedule flight: every per-sample law
    # without a gains file (the law cannot run), then prepare() before the flight and a block.
    code = ("from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config\n"
            "from aero_dva.control.switching_io import with_per_sample\n"
            "from aero_dva_sim.simulator_spec import PER_SAMPLE_FILES\n"
            "config = load_runtime_config({})\n"
            "for entry, option in PER_SAMPLE_FILES:\n"
            "    config = with_per_sample(config, entry.source, '', '')\n"
            "runtime = FlightRuntime(config)\n"
            "runtime.prepare()\n"
            "runtime.step()\n")
    imported = _modules(code)
    assert "numpy" in imported and not imported & {"scipy", "numba"}
