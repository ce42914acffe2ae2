"""The controller table: its entries are consistent, the tools read it, and what a flight
summary expects of each controller follows from the input its commands answer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from aero_dva.bag import channels as ch
from aero_dva.control import controllers as table
from aero_dva.control.controllers import (
    BLOCK,
    CONDITION,
    REFERENCE,
    SAMPLE,
    SPECTRUM,
    TICK,
    Condition,
    Controller,
    LawParam,
    SpectrumInput,
)
from aero_dva.control.spectrum import DEFAULT_FREQUENCIES


def test_every_entry_is_whole():
    entries = table.controllers(builtin_only=True)
    assert [e.name for e in entries] == ["fixed", "schedule", "rbf", "switching",
                                         "clipped_optimal", "oracle"]
    assert len({e.source for e in entries}) == len(entries)
    assert len({e.node for e in entries}) == len(entries)
    for entry in entries:
        assert entry.runs in (BLOCK, SAMPLE, REFERENCE)
        assert table.by_source(entry.source) is entry
        for kind in entry.node_reads:
            assert kind in ch.LAW_INPUTS  # a topic carries every input a node reads
        if entry.runs == BLOCK:
            assert callable(table.load_callable(entry.law))
    assert table.by_source("switching_fallback").name == "switching"
    assert table.controller("rbf").helpers == ("spectrum",)
    assert table.controller("rbf").node_reads == ("acceleration", "damper_state")


@pytest.mark.parametrize("name, expected", [
    ("schedule", 39), ("rbf", 7), ("fixed", 40), ("switching", 40)])
def test_expected_commands(name, expected):
    # 40 blocks of 50 ms: 2 s; the fixed controller and the switching supervisor at 20 Hz
    assert table.expected_commands(table.controller(name), 40, 0.05, 7) == expected
    assert table.expected_commands(None, 40, 0.05, 7) == 0


def test_an_unknown_name_is_refused_naming_the_known_ones():
    with pytest.raises(ValueError, match="unknown controller 'nope': known are fixed, schedule"):
        table.controller("nope")


def test_a_bad_entry_is_refused():
    with pytest.raises(ValueError, match="inputs"):
        Controller("x", "x", "x", BLOCK, "m:f", ("telepathy",), 0.1, "")
    with pytest.raises(ValueError, match="rate"):
        Controller("x", "x", "x", BLOCK, "m:f", (TICK,), 0.1, "")
    with pytest.raises(ValueError, match="only a reference"):
        Controller("x", "x", "x", BLOCK, "m:f", ("truth",), 0.1, "")
    with pytest.raises(ValueError, match="identifier"):
        Controller("none", "x", "x", BLOCK, "m:f", (CONDITION,), 0.1, "")


def test_the_laws_answer_their_inputs():
    fixed = table.controller("fixed").make_law({"damping": 700.0})
    assert fixed.answer(TICK, 0, None).damping == 700.0
    with pytest.raises(ValueError, match="'damping' must be in"):
        fixed.set("damping", -1.0)
    schedule = table.controller("schedule").make_law({"a0": -2000.0, "a1": 30.0})
    step = schedule.answer(CONDITION, 0, Condition(100.0, 1.2))
    assert step.kind == "command" and step.damping == 1000.0
    rejected = schedule.answer(CONDITION, 1, Condition(math.nan, 1.2))
    assert rejected.kind == "rejected" and "airspeed" in rejected.reason


def test_a_law_of_spectra_rejects_a_spectrum_of_another_shape(tmp_path):
    from aero_dva.control.rbf_io import save_rbf_network
    from aero_dva.control.rbf_network import spectrum_input_names, train_rbf_ols

    rng = np.random.default_rng(0)
    mags = rng.dirichlet(np.ones(16), size=(40, 2))
    inputs = np.column_stack([mags.reshape(40, 32), rng.uniform(300, 1500, 40)])
    names, units = spectrum_input_names()
    net = train_rbf_ols(inputs, 400 + 3000 * mags[:, 0, 7], spread=2.0, max_neurons=8,
                        input_names=names, input_units=units).network
    path = save_rbf_network(net, tmp_path / "net.npz")
    law = table.controller("rbf").make_law({"network_file": str(path)})
    good = SpectrumInput(5, ("plunge", "pitch"), DEFAULT_FREQUENCIES.copy(), mags[0], 2.0,
                         "rectangular", "band_sum", 600.0)
    step = law.answer(SPECTRUM, 5, good)
    assert step.kind == "command" and step.damping == law.command(mags[0], 600.0)[0]
    hann = SpectrumInput(5, ("plunge", "pitch"), DEFAULT_FREQUENCIES.copy(), mags[0], 2.0,
                         "hann", "band_sum", 600.0)
    assert law.answer(SPECTRUM, 5, hann).reason == "window 'hann', network has 'rectangular'"
    with pytest.raises(ValueError, match="required"):
        table.controller("rbf").make_law()


def test_law_params_are_the_node_params_fields():
    from dataclasses import fields

    node_params = pytest.importorskip("dva_ros_common.node_params")
    assert [f.name for f in fields(LawParam)] == [f.name for f in fields(node_params.Param)]


def test_the_fixed_controllers_default_is_the_best_constant_c2_of_the_default_wing():
    """Its --help says so: the c2 with the highest flutter airspeed of the chapter-6 wing (the
    fixed controller dva evaluate flies), to the 0.1 N s/m the table keeps."""
    from aero_dva.control.controllers import BEST_FIXED_DAMPING, controller
    from aero_dva.control.dva_design import best_fixed_damping
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import load_wing

    cfg = load_wing()
    best = best_fixed_damping(AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero),
                              cfg.air_density)
    assert round(best.damping, 1) == BEST_FIXED_DAMPING == controller("fixed").defaults()[
        "damping"]
    assert "best constant c2" in controller("fixed").params[0].description
