"""config/graph.yaml sets the nodes as run_flight does (needs the built workspace, no DDS).

Every parameter run_flight passes the recorder, the fixed controller and the simulator of a
``--controller fixed`` flight has the same value in the file, or is the node's default there
(the bag's name aside), the
file sets nothing else but the damper's start-up and fallback c2, which are the wing file's
design c2 (what the simulator takes when run_flight leaves them out), and every node's section
names only parameters it declares.
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

pytest.importorskip("dva_msgs.msg", reason="needs the built workspace (source scripts/env.sh)")

from aero_dva.control.controllers import controller  # noqa: E402
from aero_dva.wing.wing_io import load_wing  # noqa: E402
from aero_dva_sim import mcap_recorder_node, run_flight, simulator_node  # noqa: E402
from dva_controller.controller_node import node_spec  # noqa: E402

GRAPH = Path(__file__).resolve().parents[3] / "config" / "graph.yaml"
SPECS = {"simulator": simulator_node.SPEC, "mcap_recorder": mcap_recorder_node.SPEC,
         "fixed_controller": node_spec(controller("fixed"))}


def _sections() -> dict:
    text = yaml.safe_load(GRAPH.read_text())
    return {node: body["ros__parameters"] for node, body in text.items()}


def _run_flights_parameters() -> dict[str, dict]:
    """Node -> {parameter: value} of ``run_flight --controller fixed``'s command lines."""
    args = run_flight.build_parser().parse_args(["--controller", "fixed"])
    out = {}
    for node, argv in run_flight.build_commands(args, Path("bag")).items():
        values = [argv[i + 1] for i, a in enumerate(argv) if a == "-p"]
        out[node] = {k: yaml.safe_load(v) for k, v in (p.split(":=", 1) for p in values)}
    return out


def test_every_node_runs_with_run_flights_values():
    sections, shared = _sections(), _sections()["/**"]
    for node, values in _run_flights_parameters().items():
        mine = {**shared, **sections.get(node, {})}
        for name, value in values.items():
            if name == "output":
                continue
            # a value the file leaves out is the node's default
            have = mine[name] if name in mine else SPECS[node][name].default
            assert have == value, (node, name, have, value)


def test_the_file_sets_nothing_run_flight_does_not_but_the_wings_design_c2():
    sections, flown = _sections(), _run_flights_parameters()
    design = load_wing().absorber.damping
    for node, values in sections.items():
        if node == "/**":
            assert values == {"use_sim_time": True}
            continue
        extra = set(values) - set(flown[node]) - {"output"}
        if node == "fixed_controller":  # run_flight flies the node's default c2
            assert values.pop("damping") == SPECS[node]["damping"].default
            extra.discard("damping")
        assert extra <= {"damper_initial", "damper_fallback"}, (node, extra)
        assert all(values[k] == design for k in extra)


@pytest.mark.parametrize("node", sorted(SPECS))
def test_each_section_names_parameters_its_node_declares(node):
    declared = {p.name for p in SPECS[node].params} | {"use_sim_time"}
    assert set(_sections().get(node, {})) <= declared


PAGE = GRAPH.parents[1] / "docs" / "nodes.md"


@pytest.mark.parametrize("name", ["fixed", "schedule", "rbf"])
def test_the_pages_table_of_other_controllers_is_run_flights(name):
    """docs/nodes.md's row of a controller: its nodes and the simulator's values run_flight
    passes for it."""
    rows = {cells[0]: cells[1:] for cells in (
        [c.strip() for c in line.strip("|").split("|")]
        for line in PAGE.read_text().splitlines() if line.startswith(f"| {name} |"))}
    nodes, lag, first, wait_nodes, wait_topics = rows[name]
    args = run_flight.build_parser().parse_args(["--controller", name])
    commands = run_flight.build_commands(args, Path("bag"))
    sim = {k: v for k, v in (a.split(":=", 1) for a in commands["simulator"] if ":=" in a)}
    assert [n.strip() for n in nodes.split(",")] == [
        n for n in commands if n not in ("mcap_recorder", "simulator")]
    assert (float(lag), float(first)) == (float(sim["max_command_lag"]),
                                          float(sim["first_input_time"]))
    assert yaml.safe_load(wait_nodes) == yaml.safe_load(sim["wait_for_nodes"])
    assert yaml.safe_load(wait_topics) == yaml.safe_load(sim["wait_for_topics"])
