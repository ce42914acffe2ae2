"""A flight with a per-sample law flown again with the c2 it recorded gives its accelerations
(what ``dva replay --offline`` checks on a bag), and another c2 gives others."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control.switching_io import with_switching
from aero_dva.data_files import data_file
from aero_dva.flight.damper import SWITCHING_SOURCE
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.per_sample.replay import fly_again

SAFE_C2 = 624.7  # [N s/m]


def _switching_runtime(folder, duration, start, end, seed):
    """The config and runtime of a switching law (10 ms damper lag) on a ramp start..end U_cr."""
    scenario = folder / "ramp.yaml"
    scenario.write_text(f"name: ramp\nduration: {duration}\nblock_size: 50\n"
                        f"airspeed: {{kind: ramp, start_ratio: {start}, end_ratio: {end}}}\n"
                        f"excitation: {{force_std: 1000.0, seed: {seed}}}\n")
    config = load_runtime_config({"scenario": str(scenario), "damper_time_constant": 0.01})
    config = with_switching(config, str(data_file("switching_gains.json")))
    return config, FlightRuntime(config)


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A 3 s ramp through 1.0 .. 1.15 U_cr: the law armed from the third block on, the first
    two blocks on the start-up and then a held c2 (a block of each kind)."""
    config, rt = _switching_runtime(tmp_path_factory.mktemp("replay"), 3.0, 1.0, 1.15, seed=4)
    blocks = []
    while not rt.done:
        if len(blocks) == 1:
            rt.command(800.0, "fixed")
        elif len(blocks) >= 2:
            rt.command(SAFE_C2, SWITCHING_SOURCE)
        blocks.append(rt.step())
    return config, rt.critical_airspeed, blocks


def test_the_recorded_c2_flies_the_recorded_accelerations(flight):
    config, u_cr, blocks = flight
    law = np.concatenate([np.full(b.n, b.damper_force is not None) for b in blocks])
    assert not law[:100].any() and law[100:].all()
    force = np.concatenate([b.force for b in blocks])
    damping = np.concatenate([b.damping for b in blocks])
    recorded = np.concatenate([b.accelerations for b in blocks], axis=1)
    assert np.unique(damping[100:]).size > 10  # the lagged c2 moved sample by sample
    again = fly_again(config, force, damping, law, u_cr)
    peak = np.abs(recorded).max(axis=1)
    assert np.all(np.abs(again.accelerations - recorded).max(axis=1) <= 1e-9 * peak)
    # another c2 over the law's blocks is another flight
    other = fly_again(config, force, np.where(law, SAFE_C2, damping), law, u_cr)
    assert np.abs(other.accelerations - recorded).max() > 1e-3 * peak.max()


def test_a_law_over_part_of_a_block_is_refused(flight):
    config, u_cr, blocks = flight
    n = sum(b.n for b in blocks)
    law = np.zeros(n, dtype=bool)
    law[120:] = True
    with pytest.raises(ValueError, match="part of a block"):
        fly_again(config, np.zeros(n), np.full(n, SAFE_C2), law, u_cr)


def test_a_flight_past_the_fixed_c2s_flutter_is_flown_again_to_the_bit_order(tmp_path):
    """Above flutter the wing under the recorded c2 sequence amplifies any rounding (60 to 150
    times per second at 1.17-1.2 U_cr): a product taken in another order than the compiled
    loop's grows from 1e-16 to beyond 1e-9 of the peak within seconds. The state is stepped in the
    loop's order, so the recorded accelerations come out whatever the flight's length."""
    config, rt = _switching_runtime(tmp_path, 8.0, 1.12, 1.2, seed=1)
    blocks = []
    while not rt.done:
        rt.command(SAFE_C2, SWITCHING_SOURCE)
        blocks.append(rt.step())
    law = np.concatenate([np.full(b.n, b.damper_force is not None) for b in blocks])
    assert law[50:].all() and not blocks[-1].diverged and len(blocks) == 160
    force = np.concatenate([b.force for b in blocks])
    damping = np.concatenate([b.damping for b in blocks])
    recorded = np.concatenate([b.accelerations for b in blocks], axis=1)
    again = fly_again(config, force, damping, law, rt.critical_airspeed)
    peak = np.abs(recorded).max(axis=1)
    assert np.all(np.abs(again.accelerations - recorded).max(axis=1) <= 1e-9 * peak)
