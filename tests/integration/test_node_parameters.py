"""Each node declares exactly the parameters of its table (the one --help prints)."""
from __future__ import annotations

import pytest
from rclpy.parameter import Parameter

from aero_dva_sim.mcap_recorder_node import McapRecorder
from aero_dva_sim.simulator_node import Simulator
from dva_controller.controller_node import law_node
from dva_controller.spectrum_node import SpectrumNode

AirspeedController, FixedController = law_node("schedule"), law_node("fixed")

pytestmark = pytest.mark.ros

ROS_OWN = ("use_sim_time", "start_type_description_service")  # rclpy declares these itself


@pytest.mark.parametrize("node_class", [FixedController, SpectrumNode, AirspeedController,
                                        Simulator, McapRecorder],
                         ids=lambda c: c.__name__)
def test_declared_parameters_are_the_table(node_class, ros_context, tmp_path):
    overrides = [Parameter("output", value=str(tmp_path / "bag"))] \
        if node_class is McapRecorder else []
    spec = getattr(node_class, "SPEC", None) or \
        __import__(node_class.__module__, fromlist=["SPEC"]).SPEC
    node = node_class(context=ros_context, parameter_overrides=overrides)
    try:
        declared = set(node.get_parameters_by_prefix("")) - set(ROS_OWN)
        assert declared == {p.name for p in spec.params}
        # a parameter read at start-up refuses a change while the node runs
        fixed = spec.read_at_start[0]
        result = node.set_parameters([Parameter(fixed, value=node.get_parameter(fixed).value)])
        assert not result[0].successful and "start-up" in result[0].reason
    finally:
        if hasattr(node, "close"):
            node.close()
        node.destroy_node()


def test_fixed_controller_damping_changes_at_run_time_within_its_range(ros_context):
    node = FixedController(context=ros_context)
    try:
        assert node.set_parameters([Parameter("damping", value=800.0)])[0].successful
        assert not node.set_parameters([Parameter("damping", value=-1.0)])[0].successful
    finally:
        node.destroy_node()


@pytest.mark.parametrize("node_class", [FixedController, SpectrumNode, AirspeedController,
                                        Simulator, McapRecorder],
                         ids=lambda c: c.__name__)
def test_a_parameter_the_node_does_not_declare_is_refused(node_class, ros_context, tmp_path):
    """A misspelt parameter (``-p dampng:=750.0``) stops the node with its name, instead of
    being ignored while the node runs on its default."""
    overrides = [Parameter("dampng", value=750.0)]
    if node_class is McapRecorder:
        overrides.append(Parameter("output", value=str(tmp_path / "bag")))
    with pytest.raises(ValueError, match=r"unknown parameter 'dampng': \w+ has .* \(see --help\)"):
        node_class(context=ros_context, parameter_overrides=overrides)
    assert not (tmp_path / "bag").exists()


def test_a_parameter_its_mode_has_no_use_for_is_refused(ros_context):
    """The simulator's DVA values with absorber:=none, the airspeed controller's a0/a1 beside a
    schedule file (whose line replaces them) and extrapolate without one: one line each."""
    from dva_controller.controller_node import ControllerNode

    with pytest.raises(ValueError, match="parameter 'absorber_mass' sets the DVA, but absorber "
                                         "is 'none'"):
        Simulator(context=ros_context, parameter_overrides=[
            Parameter("absorber", value="none"), Parameter("absorber_mass", value=40.0)])
    with pytest.raises(ValueError, match="parameter 'a0' has no use with 'schedule_file' set"):
        ControllerNode("schedule", context=ros_context, parameter_overrides=[
            Parameter("schedule_file", value="schedule.json"), Parameter("a0", value=-1000.0)])
    with pytest.raises(ValueError, match="parameter 'extrapolate' acts only with "
                                         "'schedule_file' set"):
        ControllerNode("schedule", context=ros_context, parameter_overrides=[
            Parameter("extrapolate", value=False)])
