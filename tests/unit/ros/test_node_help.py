"""Every executable of the ROS packages answers --help/-h without starting, and refuses unknown
arguments; the help is the node's own parameter table (needs the built workspace, no DDS)."""
from __future__ import annotations

import importlib
import importlib.metadata
import subprocess
from pathlib import Path

import pytest
import yaml

pytest.importorskip("dva_msgs.msg", reason="needs the built workspace (source scripts/env.sh)")

from ament_index_python.packages import get_package_prefix, get_package_share_directory  # noqa: E402

from aero_dva import exits  # noqa: E402
from dva_ros_common.node_params import NodeSpec, Param, check_value, help_text  # noqa: E402

PACKAGES = ("aero_dva_sim", "dva_controller")
HELP_TIMEOUT = 120.0  # [s] a guard against a hang; how fast --help answers is a bench figure


def entry_points() -> list[tuple[str, str, str]]:
    """(package, executable, module) of every console script the packages' setup.py declare."""
    found = []
    for package in PACKAGES:
        for ep in importlib.metadata.distribution(package).entry_points:
            if ep.group == "console_scripts":
                found.append((package, ep.name, ep.value.partition(":")[0]))
    return sorted(found)


ENTRY_POINTS = entry_points()


def node_spec(executable: str, module: str):
    """The parameter table an executable's node declares: its module's ``SPEC``, or for an
    alias of a law's node (the generic controller node, a per-sample law's supervisor) its
    law's (None: a plain command)."""
    from aero_dva.control.controllers import by_node

    code = importlib.import_module(module)
    entry = by_node(executable)
    if entry is not None and hasattr(code, "node_spec"):  # an alias of a law's node
        return code.node_spec(entry)
    return getattr(code, "SPEC", None)


def _run(package: str, executable: str, *args: str) -> subprocess.CompletedProcess:
    path = Path(get_package_prefix(package)) / "lib" / package / executable
    return subprocess.run([str(path), *args], capture_output=True, text=True,
                          timeout=HELP_TIMEOUT)


def test_the_packages_declare_the_nodes_of_the_issue():
    names = {name for _, name, _ in ENTRY_POINTS}
    assert {"simulator", "mcap_recorder", "bag_player", "spectrum", "fixed_controller",
            "airspeed_controller", "rbf_controller"} <= names


@pytest.mark.parametrize(("package", "executable", "module"), ENTRY_POINTS,
                         ids=[e for _, e, _ in ENTRY_POINTS])
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_lists_every_parameter_and_exits_0(package, executable, module, flag):
    result = _run(package, executable, flag)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("usage:") and not result.stderr.strip(), result.stderr
    said = " ".join(result.stdout.split())  # every executable says the one exit-code table
    for code, meaning in exits.TABLE.items():
        assert f"{code} {' '.join(meaning.split())}" in said, (executable, code)
    spec = node_spec(executable, module)
    if spec is None:  # a plain command (run_flight, the generic controller): its own help
        return
    assert spec.name == executable and spec.package == package
    for param in spec.params:
        assert f"  {param.name} ({param.type_name}" in result.stdout, param.name
        if param.unit:
            assert f"[{param.unit}]" in result.stdout, param.name
    assert result.stdout == help_text(spec)


@pytest.mark.parametrize(("package", "executable", "module"), ENTRY_POINTS,
                         ids=[e for _, e, _ in ENTRY_POINTS])
def test_unknown_option_is_refused_with_exit_2(package, executable, module):
    result = _run(package, executable, "--no-such-option")
    assert result.returncode == 2, result.stdout + result.stderr
    last = result.stderr.strip().splitlines()[-1]  # argparse prints its usage first
    assert f"{executable}: error: " in last and "Traceback" not in result.stderr, result.stderr
    if node_spec(executable, module) is not None:
        assert "unrecognized arguments: --no-such-option" in last, result.stderr


def test_help_does_not_start_the_node(tmp_path):
    bag = tmp_path / "bag"
    result = _run("aero_dva_sim", "mcap_recorder", "--help", "--ros-args", "-p",
                  f"output:={bag}")
    assert result.returncode == 0 and not bag.exists()
    # --help among the ROS arguments is help too (rcl would refuse it as unknown)
    result = _run("aero_dva_sim", "mcap_recorder", "--ros-args", "-p", f"output:={bag}",
                  "--help")
    assert result.returncode == 0 and "output (string)" in result.stdout and not bag.exists()


def test_the_generic_controller_runs_a_law_of_the_table_by_name():
    aliased = _run("dva_controller", "rbf_controller", "--help")
    named = _run("dva_controller", "controller", "rbf", "--help")
    assert named.returncode == 0 and named.stdout == aliased.stdout
    listing = _run("dva_controller", "controller", "--help")
    assert listing.returncode == 0 and "laws: fixed, schedule, rbf" in listing.stdout
    unknown = _run("dva_controller", "controller", "nope")
    assert unknown.returncode == 2 and "unknown controller 'nope'" in unknown.stderr
    sample = _run("dva_controller", "controller", "switching")
    assert sample.returncode == 2 and "does not run in a controller node" in sample.stderr


def test_malformed_ros_arguments_are_one_line_errors():
    result = _run("dva_controller", "fixed_controller", "--ros-args", "-p", "damping")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr


@pytest.mark.parametrize("package", PACKAGES)
def test_example_config_files_set_only_declared_parameters(package):
    """The config/*.yaml examples name parameters of the node's table (no drift)."""
    specs = {}
    for _, executable, module in ENTRY_POINTS:
        spec = node_spec(executable, module)
        if spec is not None:
            specs[spec.name] = spec
    files = sorted(Path(get_package_share_directory(package), "config").glob("*.yaml"))
    assert files
    for path in files:
        for node, section in yaml.safe_load(path.read_text()).items():
            declared = {p.name for p in specs[node].params} | {"use_sim_time"}
            unknown = set(section["ros__parameters"]) - declared
            assert not unknown, (path.name, unknown)
            for name, value in section["ros__parameters"].items():
                if name != "use_sim_time" and name != "output":
                    check_value(specs[node][name], value)


def test_table_rows_check_their_ranges_and_choices():
    damping = Param("damping", 1500.0, "c2", "N s/m", 0.0, 1.0e6)
    assert check_value(damping, 10.0) == 10.0
    with pytest.raises(ValueError, match=r"parameter 'damping' must be in \[0, 1e\+06\] N s/m"):
        check_value(damping, -1.0)
    with pytest.raises(ValueError, match="is NaN"):
        check_value(damping, float("nan"))
    mass = Param("mass", float("nan"), "m", "kg", 0.0, 10.0, nan_means="the file's value")
    assert check_value(mass, float("nan")) != check_value(mass, float("nan"))  # NaN passes
    window = Param("window", "hann", "w", choices=("hann", "rectangular"))
    with pytest.raises(ValueError, match="one of"):
        check_value(window, "blackman")
    channels = Param("channels", ["a"], "c", choices=("a", "b"))
    assert check_value(channels, [""]) == [""]  # rcl's typed empty array
    with pytest.raises(ValueError, match="'c'"):
        check_value(channels, ["a", "c"])
    freqs = Param("frequencies", [5.0, 6.0], "f", "Hz", low=1e-9)
    with pytest.raises(ValueError, match="frequencies"):
        check_value(freqs, [5.0, -1.0])
    with pytest.raises(ValueError, match="twice"):
        NodeSpec("n", "p", "s", (damping, damping))
