"""Closed loop over DDS with sim time: simulator -> (spectrum ->) controller -> simulator.

At an airspeed chosen from the model (above the flutter speed of the wing whose damper is stuck
at a poor c2, below the flutter speed of the wing with c2 tuned per airspeed, and where the
stuck damper grows slowly enough for a first 2 s spectrum window), the wing starts with the
poor c2; the airspeed schedule, and the RBF network fed by the spectrum node, each take
the loop to a bounded flight, while the stuck damper diverges.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter

from aero_dva.control.airspeed_schedule import fit_airspeed_schedule
from aero_dva.control.dva_design import best_damping_curve
from aero_dva.control.rbf_io import save_rbf_network
from aero_dva.control.rbf_network import select_spread, spectrum_input_names, train_rbf_ols
from aero_dva.control.spectrum import scaled_spectrum
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, Scenario
from aero_dva.wing.flutter import flutter_speed, growth_rate
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing
from aero_dva_sim.simulator_node import Simulator
from dva_controller.controller_node import law_node
from dva_controller.spectrum_node import SpectrumNode
from dva_msgs.msg import (
    AccelerationBlock,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)

AirspeedController, FixedController, RBFController = (
    law_node(n) for n in ("schedule", "fixed", "rbf"))

pytestmark = pytest.mark.ros

POOR_C2 = 2500.0  # [N s/m] the damper's top end: far from the optimum at high airspeed
MAX_GROWTH = 1.5  # [1/s] of the stuck damper at the test airspeed


@pytest.fixture(scope="module")
def design():
    """Schedule (eq. 7.1 fitted to the damping-optimal c2) and a test airspeed from the model."""
    config = load_wing()
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    u_poor = flutter_speed(model, 1.2, damping=POOR_C2).critical_airspeed
    airspeeds = np.linspace(0.95 * u_poor, 1.3 * u_poor, 15)
    tuned = best_damping_curve(model, airspeeds, 1.2)
    stable = [s for s in tuned if s.min_damping_ratio > 0.01]
    fit = fit_airspeed_schedule([s.airspeed for s in stable], [s.damping for s in stable],
                                (0.0, POOR_C2))
    # The highest such airspeed at which the stuck damper grows slowly enough for the spectrum
    # node to fill its first 2 s window before the wing diverges (e^(2 s * 1.5/s) = 20x).
    slow = [s for s in stable
            if np.max(growth_rate(model, s.airspeed, 1.2, damping=POOR_C2)) <= MAX_GROWTH]
    u_test = round(slow[-1].airspeed, 3)  # as written to the scenario file
    assert u_test > u_poor + 2.0, "the model offers no airspeed where scheduling matters"
    growth = float(np.max(growth_rate(model, u_test, 1.2, damping=POOR_C2)))
    duration = float(np.clip(12.0 / growth, 5.0, 40.0))  # e^12: far beyond the stop limit
    return {"schedule": fit.schedule, "airspeed": u_test, "duration": duration,
            "tuned": {s.airspeed: s.damping for s in tuned}, "model": model}


@pytest.fixture(scope="module")
def network_file(design, tmp_path_factory):
    """An RBF network (eq. 7.4-7.5, OLS) trained on simulated test points: 2 s windows of
    plunge and pitch accelerations at several airspeeds and c2 values, labelled with the
    damping-optimal c2 of the airspeed (a miniature of the study's sec. 7.2.1 experiment; each
    point starts from rest, and settings unstable at an airspeed are skipped, as an experiment
    would have to)."""
    config = load_runtime_config({})
    airspeeds = [u for u in sorted(design["tuned"]) if u <= design["airspeed"]]
    dwell = 4.0  # 2 s to settle, then the 2 s window
    inputs, targets = [], []
    for u in airspeeds:
        best = design["tuned"][u]
        for c2 in best * np.array([0.5, 0.7, 0.85, 1.0, 1.2, 1.45, 2.0, 3.0]):
            if np.max(growth_rate(design["model"], u, 1.2, damping=c2)) >= 0:
                continue
            point = Scenario("point", dwell, block_size=100, airspeed=AirspeedProfile(
                "steps", (u,)), dwell=dwell, sweep_damping=(float(c2),), seed=len(inputs))
            runtime = FlightRuntime(dataclasses.replace(config, scenario=point))
            acc = np.concatenate([runtime.step().accelerations[:2] for _ in range(40)], axis=1)
            window = scaled_spectrum(acc[:, 2000:], 1000.0)
            inputs.append(np.append(window.magnitudes.ravel(), c2))
            targets.append(best)
    inputs, targets = np.array(inputs), np.array(targets)
    assert len(targets) >= 20
    held_out = np.arange(len(targets)) % 4 == 0
    spread = select_spread(inputs[~held_out], targets[~held_out], inputs[held_out],
                           targets[held_out], spreads=(0.3, 0.6, 1.2, 2.4)).best_spread
    names, units = spectrum_input_names()
    network = train_rbf_ols(inputs, targets, spread, input_names=names,
                            input_units=units).network
    return save_rbf_network(network, tmp_path_factory.mktemp("rbf") / "network.npz")


def _fly(executor, spin, ros_context, tmp_path, design, *controllers: Node, lag: float = 0.2,
         first_input: float = 0.0):
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(f"name: hold\nduration: {design['duration']:.3f}\nblock_size: 50\n"
                        f"airspeed: {{kind: constant, value: {design['airspeed']}}}\n"
                        "excitation: {force_std: 1000.0, seed: 5}\n")
    sim = Simulator(context=ros_context, parameter_overrides=[
        Parameter("scenario", value=str(scenario)), Parameter("real_time_factor", value=0.0),
        Parameter("wait_for_subscribers", value=1), Parameter("damper_timeout", value=5.0),
        # The flight starts with the damper at the poor setting: only the controller can save it.
        Parameter("damper_initial", value=POOR_C2), Parameter("damper_fallback", value=POOR_C2),
        Parameter("max_command_lag", value=lag),
        # the flight holds past the controller's first input until its first command
        Parameter("first_input_time", value=first_input)])
    probe = Node("probe", context=ros_context)
    states, blocks = [], []
    probe.create_subscription(DamperState, "dva/damper_state", states.append, 5000)
    probe.create_subscription(AccelerationBlock, "wing/acceleration", blocks.append, 5000)
    # The simulator starts when every data topic has a subscriber.
    for msg_type, topic in ((ForceBlock, "wing/excitation"), (FlightCondition, "flight/condition"),
                            (DisplacementBlock, "wing/displacement")):
        probe.create_subscription(msg_type, topic, lambda _: None, 10)
    for node in (*controllers, probe, sim):
        executor.add_node(node)
    assert spin(executor, sim.finished.done, timeout=120.0)
    spin(executor, lambda: len(states) >= sim.published["dva/damper_state"], timeout=5.0)
    return sim.finished.result(), states


def _sim_time(use: bool = True) -> list[Parameter]:
    return [Parameter("use_sim_time", value=use)]


def test_scheduled_damper_keeps_the_wing_bounded(executor, spin, ros_context, tmp_path, design):
    schedule = design["schedule"]
    controller = AirspeedController(context=ros_context, parameter_overrides=_sim_time() + [
        Parameter("a0", value=schedule.a0), Parameter("a1", value=schedule.a1)])
    outcome, states = _fly(executor, spin, ros_context, tmp_path, design, controller)
    assert outcome == "completed"
    scheduled = [s for s in states if s.source == "airspeed_schedule"]
    assert len(scheduled) > 0.9 * len(states)  # the loop closed within the first blocks
    expected = schedule.evaluate(design["airspeed"])
    assert scheduled[-1].applied_damping == pytest.approx(expected, rel=1e-9)


def test_spectrum_rbf_loop_keeps_the_wing_bounded(executor, spin, ros_context, tmp_path,
                                                  design, network_file):
    spectrum = SpectrumNode(context=ros_context, parameter_overrides=_sim_time())
    rbf = RBFController(context=ros_context, parameter_overrides=_sim_time() + [
        Parameter("network_file", value=str(network_file))])
    outcome, states = _fly(executor, spin, ros_context, tmp_path, design, spectrum, rbf,
                           lag=0.15, first_input=2.0)  # the first spectrum: a 2 s window
    assert outcome == "completed"
    from_network = [s for s in states if s.source == "rbf_network"]
    assert from_network, "the network never commanded the damper"
    assert from_network[-1].applied_damping < 0.5 * POOR_C2  # moved well away from the start


def test_stuck_poor_damper_diverges(executor, spin, ros_context, tmp_path, design):
    controller = FixedController(context=ros_context, parameter_overrides=_sim_time() + [
        Parameter("damping", value=POOR_C2), Parameter("rate", value=20.0)])
    outcome, states = _fly(executor, spin, ros_context, tmp_path, design, controller)
    assert outcome == "diverged"
    assert states[-1].applied_damping == POOR_C2

