"""Physically absurd numbers in every numeric field of every input file and every numeric node
parameter (bench/faults/number_fuzz.py, the bench's whole set): each is accepted inside its
stated range or refused in one line, never an internal error, a hang or a MemoryError."""
from __future__ import annotations

import collections

import pytest

from bench.faults import number_fuzz

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def trials(tmp_path_factory):
    pytest.importorskip("dva_msgs.msg", reason="the node tables need the built workspace")
    work = tmp_path_factory.mktemp("numbers")
    return list(number_fuzz.file_trials(work)) + list(number_fuzz.parameter_trials(work))


def test_every_trial_is_accepted_or_refused_in_one_line(trials):
    bad = [t for t in trials if t.outcome not in ("accepted", "refused")]
    assert not bad, bad[:10]
    assert len(trials) > 1000


def test_the_issues_cases_are_refused(trials):
    by = {(t.kind, t.field, t.value_class): t for t in trials}
    for key, words in [
        (("scenario", "excitation.force_std", "zero"), "force_std must be in"),
        (("scenario", "duration", "small"), "shorter than one block"),
        (("scenario", "sample_rate", "large"), "sample_rate must be in [100, 20000] Hz"),
        (("wing file", "wing.elastic_axis", "huge"), "elastic_axis must be in [-100, 100] m"),
        (("training plan", "critical_airspeed", "zero"), "critical_airspeed must be in"),
    ]:
        assert by[key].outcome == "refused" and words in by[key].message, (key, by[key])


def test_nan_and_infinity_are_never_accepted_outside_a_stated_meaning(trials):
    accepted = collections.Counter((t.kind, t.field) for t in trials
                                   if t.value_class in ("NaN", "infinite")
                                   and t.outcome == "accepted")
    # NaN of a simulator parameter means the wing file's value; inf of an absorber's c2 is a
    # locked damper (both stated in the ranges)
    assert set(accepted) <= {("node simulator", p) for p in (
        "absorber_mass", "absorber_stiffness", "absorber_series_stiffness",
        "absorber_position", "damper_initial", "damper_fallback")} | {
        ("wing file", "absorber.damping")}, accepted
