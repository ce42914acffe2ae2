"""The domain package and the offline CLI import on a machine without ROS.

Every module of ``aero_dva`` and ``dva_offline`` is imported in a fresh interpreter in which
importing ``rclpy``, ``dva_msgs`` or any ROS message package fails, as it does where ROS is not
installed; and the layers of ``aero_dva`` import only the layers below them.
"""
from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
PACKAGE_DIRS = [REPO / "aero_dva/aero_dva", REPO / "offline/dva_offline"]
# Packages that only a ROS installation provides (the project's ROS packages included).
ROS_ONLY = ("rclpy", "rcl_interfaces", "builtin_interfaces", "diagnostic_msgs", "rosgraph_msgs",
            "std_msgs", "dva_msgs", "aero_dva_sim", "dva_controller", "dva_ros_common",
            "ament_index_python")
# What each layer of aero_dva may import (besides the package root's modules).
ALLOWED = {"wing": set(), "flight": {"wing"}, "control": {"wing", "flight"},
           "bag": {"wing", "flight"}}

BLOCKER = """
import importlib.abc, sys
class NoRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {blocked!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}} (ROS is not installed)")
        return None
sys.meta_path.insert(0, NoRos())
"""


def modules() -> list[str]:
    out = []
    for package_dir in PACKAGE_DIRS:
        root = package_dir.parent
        for path in sorted(package_dir.rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def _import_all(names: list[str], blocked: tuple[str, ...]) -> subprocess.CompletedProcess:
    code = BLOCKER.format(blocked=set(blocked)) + (
        "import importlib, json\n"
        f"for m in {names!r}:\n"
        "    importlib.import_module(m)\n"
        "print(json.dumps(sorted(k for k in sys.modules if k.split('.')[0] in "
        f"{set(blocked)!r})))\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=180)


def test_domain_and_cli_import_without_ros():
    names = modules()
    assert "aero_dva.wing.model" in names and "dva_offline.cli" in names
    result = _import_all(names, ROS_ONLY)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1]) == []


def test_the_blocker_really_blocks():
    """The check above would catch a leak: a node module fails to import behind the blocker."""
    result = _import_all(["dva_controller.controller_node"], ROS_ONLY)
    assert result.returncode != 0
    assert "ROS is not installed" in result.stderr


def _imported_layers(path: Path) -> set[str]:
    layers = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module + "." + alias.name for alias in node.names]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        for name in names:
            parts = name.split(".")
            if parts[0] == "aero_dva" and len(parts) > 1 and parts[1] in ALLOWED:
                layers.add(parts[1])
    return layers


def test_layers_import_only_the_layers_below():
    package = REPO / "aero_dva/aero_dva"
    wrong = []
    for layer, allowed in ALLOWED.items():
        for path in sorted((package / layer).rglob("*.py")):
            for used in _imported_layers(path) - allowed - {layer}:
                wrong.append(f"{path.relative_to(REPO)} imports aero_dva.{used}")
    for path in package.glob("*.py"):  # the root's modules serve every layer
        wrong += [f"{path.relative_to(REPO)} imports aero_dva.{used}"
                  for used in _imported_layers(path)]
    assert wrong == []
