"""``dva info``: what this installation has (versions, ROS 2 availability, data paths)."""
from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import platform
import sys


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def collect() -> dict:
    """Environment facts as a JSON-ready dict (never imports rclpy: finding it is enough)."""
    return {
        "python": platform.python_version(),
        "executable": sys.executable,
        "packages": {
            name: _version(name)
            for name in ("dva-offline", "numpy", "scipy", "mcap", "mcap-ros2-support", "rosbags",
                         "rerun-sdk", "matplotlib")
        },
        "ros": {
            "rclpy_available": importlib.util.find_spec("rclpy") is not None,
            "dva_msgs_available": importlib.util.find_spec("dva_msgs") is not None,
            "ros_distro": os.environ.get("ROS_DISTRO"),
            "ament_prefix_path": os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)
            if os.environ.get("AMENT_PREFIX_PATH") else [],
        },
        "model_packages": {
            name: importlib.util.find_spec(name) is not None
            for name in ("aero_dva_sim", "dva_controller")
        },
    }


def _run(args) -> int:
    facts = collect()
    if args.json:
        print(json.dumps(facts, indent=2))
        return 0
    rows = [("python", f"{facts['python']} ({facts['executable']})")]
    rows += [(name, version or "not installed") for name, version in facts["packages"].items()]
    ros = facts["ros"]
    rows.append(("rclpy", f"{'found' if ros['rclpy_available'] else 'not found'}"
                          f" (ROS_DISTRO={ros['ros_distro'] or 'unset'})"))
    rows.append(("dva_msgs", "found" if ros["dva_msgs_available"]
                 else "not found (source scripts/env.sh)"))
    rows += [(name, "found" if found else "not found")
             for name, found in facts["model_packages"].items()]
    for label, value in rows:
        print(f"{label:<19}{value}")
    return 0


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "info", help="show versions and what is available (ROS 2, model packages)",
        description="Show the versions of the tools and whether ROS 2 and the model packages "
                    "are importable. Useful in bug reports.")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(func=_run)
