"""Acceptance of the discrepancy loop on generated data with one undeclared effect.

Randomised cases (seeds 100, 101, ...; the loop gets only the data, mass and static
stiffness, plus ``elements=1`` for the missing-element case):

* each library effect, N_EFFECT cases: named AND held-out error at most halved in all but at
  most one, and never another effect's name;
* clean data, N_CLEAN cases (half single sweeps, half three-temperature or three-level sets):
  ``consistent`` in all but at most one, never ``explained``;
* each effect outside the library, N_OUTSIDE cases: never ``explained`` (a weak partial
  attribution is reported only as evidence of an ``unexplained`` verdict), except that a
  cubic spring measured at three levels may be named ``amplitude_dependence`` (what it is at
  those levels; issue 23).

The multi-covariate data sets are the amplitude/temperature effects, the Duffing case and half
of the clean cases (test_discrepancy_frf.py adds one with two covariates). This is a fixed
sample the suite can afford; the rates (>= 90 % named and halved, >= 90 % clean consistent) are
measured on 40 fresh seeds per effect by bench/bench_discrepancy_acceptance.py, with their
figures in docs/discrepancy.md.
"""
import numpy as np
import pytest

from dva_offline.discrepancy import loop, synthetic
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.isolator.frf_data import split_conditions

N_EFFECT = 4
N_CLEAN = 4
N_OUTSIDE = 2
SEED0 = 100


def run(effect, seed, clean_covariate=None, max_steps=1):
    case = synthetic.generate_case(effect, np.random.default_rng(seed),
                                   clean_covariate=clean_covariate)
    conditions = split_conditions(case.frequency_hz, case.values, case.quantity,
                                  case.covariates, list(case.condition_columns))
    fixed = case.n_elements if effect == "maxwell_element" else None
    domain = FrfDomain(conditions, mass=case.mass, static_stiffness=case.static_stiffness,
                       elements=fixed)
    # the single-effect criteria are properties of the loop's first step; effects outside
    # the library run later steps too (they must not turn them into a name either)
    return loop.run(domain, rule=loop.DecisionRule(max_steps=max_steps))


@pytest.mark.slow
@pytest.mark.parametrize("effect", synthetic.LIBRARY_EFFECTS)
def test_library_effect_named_and_error_halved(effect):
    outcomes = []
    for seed in range(SEED0, SEED0 + N_EFFECT):
        res = run(effect, seed)
        named = res.verdict.status == "explained" and res.verdict.effect == effect
        halved = named and res.augmented.error <= 0.5 * res.baseline.error
        outcomes.append((named and halved, res.verdict.status, res.verdict.effect))
    hits = sum(o[0] for o in outcomes)
    assert hits >= N_EFFECT - 1, outcomes
    # never a confident wrong name
    assert all(o[2] in (None, effect) for o in outcomes), outcomes


@pytest.mark.slow
def test_clean_data_consistent():
    covariates = (None, "temperature_c", None, "excitation_n")
    statuses = [run(None, seed, covariates[i % 4]).verdict.status
                for i, seed in enumerate(range(SEED0, SEED0 + N_CLEAN))]
    assert statuses.count("consistent") >= N_CLEAN - 1, statuses
    assert "explained" not in statuses, statuses


@pytest.mark.slow
@pytest.mark.parametrize("effect", synthetic.OUTSIDE_EFFECTS)
def test_effect_outside_library_never_confidently_named(effect):
    # (three steps: the later steps of the loop on these data are checked over 20 seeds with
    # the full loop by bench/bench_discrepancy_acceptance.py; this keeps the suite's runtime)
    verdicts = [run(effect, seed, max_steps=3).verdict
                for seed in range(SEED0, SEED0 + N_OUTSIDE)]
    # A cubic spring measured at three excitation levels is an amplitude dependence of the
    # mount (issue 23: the Duffing oscillator at three levels): that name is right, no other.
    allowed = {"amplitude_dependence"} if effect == "cubic_stiffness" else set()
    assert all(v.status != "explained" or v.effect in allowed for v in verdicts), [
        (v.status, v.effect) for v in verdicts]
    assert all(v.status == "unexplained" for v in verdicts
               if v.status != "consistent" and v.effect not in allowed)
