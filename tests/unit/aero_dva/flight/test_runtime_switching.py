"""The switching law in the flight runtime's damper path: armed by a "switching" command it
runs every sample, and each fault leaves the damper on a constant c2 and says why."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control.switching_io import with_switching
from aero_dva.data_files import data_file
from aero_dva.flight.damper import SWITCHING_SOURCE, DamperMode, DamperStatus
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

SAFE_C2 = 624.7  # [N s/m] the best constant c2 of the chapter-6 wing


def runtime(tmp_path, ratio, duration=3.0, gains=None):
    scenario = tmp_path / "hold.yaml"
    scenario.write_text(f"name: hold\nduration: {duration}\nblock_size: 50\n"
                        f"airspeed: {{kind: constant, value_ratio: {ratio}}}\n"
                        "excitation: {force_std: 1000.0, seed: 7}\n")
    config = load_runtime_config({"scenario": str(scenario), "damper_time_constant": 0.01})
    path = str(data_file("switching_gains.json")) if gains is None else gains
    return FlightRuntime(with_switching(config, path))


def fly(rt, source, blocks=None, command_blocks=None):
    les, modes = [], []
    count = rt.scenario.n_samples // rt.block_size if blocks is None else blocks
    for b in range(count):
        if command_blocks is None or b < command_blocks:
            rt.command(SAFE_C2, source)
        block = rt.step()
        les.append(block.displacements[2])
        modes.append(rt.damper_snapshot())
    return np.concatenate(les), modes


def test_a_switching_command_runs_the_law_every_sample_and_holds_the_wing(tmp_path):
    # 1.18 U_cr lies above the best constant c2's flutter airspeed (1.1505 U_cr).
    law_rt = runtime(tmp_path, 1.18)
    le_law, states = fly(law_rt, SWITCHING_SOURCE)
    le_fixed, _ = fly(runtime(tmp_path, 1.18), "fixed")
    assert all(s.mode == DamperMode.SWITCHING for s in states)
    assert min(s.switching_rate for s in states[5:]) > 5.0
    assert law_rt.step is not None and law_rt.applied.controlled == len(states)

    def rms(x):
        return float(np.sqrt(np.mean(x**2)))

    # The constant c2 flutters (grows), the law does not.
    assert rms(le_fixed[-1000:]) > 3 * rms(le_fixed[:1000])
    assert rms(le_law[-1000:]) < 0.5 * rms(le_fixed[-1000:])


def test_invalid_gains_leave_the_commanded_constant_c2_and_say_why(tmp_path):
    bad = tmp_path / "gains.json"
    bad.write_text('{"format": "dva_switching_gains", "version": 1}')
    rt = runtime(tmp_path, 1.0, duration=0.5, gains=str(bad))
    assert rt.law_problem().startswith("invalid switching gains")
    _, states = fly(rt, SWITCHING_SOURCE)
    assert all(s.mode == DamperMode.SWITCHING_REFUSED for s in states)
    # the damper's 10 ms lag carries it to the commanded c2 and holds it there
    assert states[-1].applied_damping == pytest.approx(SAFE_C2, rel=1e-6)


def test_no_gains_file_refuses_the_law(tmp_path):
    rt = runtime(tmp_path, 1.0, duration=0.2, gains="")
    assert "no gains file for the switching law" in rt.law_problem()
    _, states = fly(rt, SWITCHING_SOURCE)
    assert states[-1].mode == DamperMode.SWITCHING_REFUSED


def test_stale_commands_end_the_law_on_the_fallback_c2(tmp_path):
    rt = runtime(tmp_path, 1.0, duration=1.5)
    _, states = fly(rt, SWITCHING_SOURCE, command_blocks=4)  # commands stop at 0.2 s
    assert states[3].mode == DamperMode.SWITCHING
    stale = [s for s in states if s.status == DamperStatus.FALLBACK_STALE]
    assert stale, "the damper never went stale"
    # the block in which the command went stale was flown by the law; every later one not
    assert len(stale) > 5
    assert all(s.mode == DamperMode.CONSTANT and s.switching_rate == 0.0 for s in stale[1:])
    fallback = rt.config.damper.fallback_damping
    assert stale[-1].applied_damping == pytest.approx(fallback, rel=1e-6)
