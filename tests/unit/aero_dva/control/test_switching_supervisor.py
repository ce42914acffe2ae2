"""The switching law's supervisor: arms the law, or holds the safe c2 and says why."""
from __future__ import annotations

import math

import numpy as np
import pytest

from aero_dva.control.switching_supervisor import FALLBACK_SOURCE, SwitchingSupervisor
from aero_dva.flight.damper import SWITCHING_SOURCE


def test_arms_the_law_when_nothing_is_wrong():
    sup = SwitchingSupervisor(624.7, 0.013, 2.0)
    cmd = sup.command(1.0)
    assert (cmd.damping, cmd.source, cmd.reason) == (624.7, SWITCHING_SOURCE, None)


def test_invalid_gains_never_arm():
    sup = SwitchingSupervisor(624.7, 0.013, 2.0, gains_problem="invalid switching gains: x")
    for t in (0.0, 10.0):
        cmd = sup.command(t)
        assert cmd.source == FALLBACK_SOURCE and cmd.reason.startswith("invalid")


def test_a_burst_disarms_until_rearm_after_its_last_sample():
    sup = SwitchingSupervisor(624.7, 0.013, 2.0)
    le = np.zeros(50)
    assert sup.observe(1.0, 1000.0, le) is None
    le[10] = 0.02  # over the limit at t = 1.01 s
    assert "0.02 m > peak_limit" in sup.observe(1.0, 1000.0, le)
    assert sup.command(1.05).source == FALLBACK_SOURCE
    assert "burst" in sup.command(3.0).reason
    assert sup.command(3.02).source == SWITCHING_SOURCE  # 2 s after the last sample over
    assert sup.bursts == 1


def test_a_non_finite_displacement_counts_as_a_burst():
    sup = SwitchingSupervisor(624.7, 0.013, math.inf)
    assert sup.observe(0.0, 1000.0, [0.0, math.nan]) is not None
    assert sup.command(1e9).source == FALLBACK_SOURCE


@pytest.mark.parametrize("args, name", [((-1.0, 0.01, 1.0), "safe_damping"),
                                        ((600.0, 0.0, 1.0), "peak_limit"),
                                        ((600.0, 0.01, -1.0), "rearm_after")])
def test_bad_settings_are_refused_by_name(args, name):
    with pytest.raises(ValueError, match=name):
        SwitchingSupervisor(*args)
