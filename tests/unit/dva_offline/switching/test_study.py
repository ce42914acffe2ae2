"""The in-process evaluation of the switching law: paired numbers that mean what they say."""
from __future__ import annotations

import math

import numpy as np

from aero_dva.control.switching_design import measured_rms
from aero_dva.control.switching_io import load_gains
from aero_dva.data_files import data_file
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing
from dva_offline.switching.study import Setting, evaluate_setting, fixed_law, paired


def test_paired_interval_of_known_values():
    out = paired([1.0, 2.0, 3.0, math.nan])
    assert out["n"] == 3 and out["mean"] == 2.0
    # t(0.975, 2) = 4.303, s = 1: half width 4.303 / sqrt(3)
    assert math.isclose(out["high"] - 2.0, 4.302652729 / math.sqrt(3), rel_tol=1e-6)


def test_fixed_law_never_switches():
    cfg = load_wing(None)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    law = fixed_law(model, 624.7)
    assert not np.any(law.gain) and law.c_lo == 624.7


def test_shipped_gains_beat_the_constant_damper_on_two_seeds():
    cfg = load_wing(None)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    gains = load_gains(data_file("switching_gains.json"))
    c2, u_cr = 624.7, 100.0
    rms = measured_rms(model, u_cr, cfg.air_density, c2, 1000.0, 1000.0)
    row = evaluate_setting(model, gains, Setting("base", 0.01, 0.05), [100, 101], u_cr, c2,
                           rms)
    assert row["practical"]["switching"] > row["practical"]["fixed"] + 0.01
    assert row["bounded"]["switching"] > row["bounded"]["fixed"]
    assert row["rms_at_1.1"]["change"]["mean"] < -0.1
    assert row["damper_power_w"]["switching"] < row["damper_power_w"]["fixed"]
    assert 10 < row["switches_per_second"]["mean"] < 200
    assert row["peak_limit_m"] > 0
