"""Effects outside the library's forms (synthetic_laws.py) through the loop: the law is found
from the per-condition fits, named with the library's effect, and recovers what those fits
reach; files with no effect stay without a name. The rates over 40 seeds are
bench/bench_discrepancy_laws.py's."""
import json

import numpy as np
import pytest

from dva_offline import cli
from dva_offline.discrepancy import cli as discrepancy_cli
from dva_offline.discrepancy import loop, synthetic_laws
from dva_offline.discrepancy.modal_domain import ModalDomain, to_receptance
from dva_offline.isolator.frf_data import split_conditions


def recovery(res):
    return ((res.baseline.error - res.final.error)
            / (res.baseline.error - res.reference.error))


@pytest.mark.parametrize("case", synthetic_laws.CASES)
def test_generators_write_what_their_docstring_says(case):
    c = synthetic_laws.generate(case, np.random.default_rng(3))
    assert c.values.shape == c.frequency_hz.shape and np.all(np.isfinite(c.values))
    assert c.effect == case
    if case in ("structure_phase", "phase_offset"):
        assert not c.covariates
        return
    col = c.covariates["temperature_c" if case == "temperature_kink" else "excitation_n"]
    sweeps = {"power_level": 5, "temperature_kink": 5, "replicates": 3,
              "structure_replicates": 3}.get(case, 4)
    assert col.size == c.values.size and col.size % sweeps == 0
    per = col.reshape(sweeps, -1).mean(axis=1)
    if case.endswith("replicates"):  # one nominal level, recorded with 1 % scatter
        assert np.ptp(per) < 0.01 * per.mean() and 0.005 < np.std(col) / col.mean() < 0.02
    else:
        assert np.all(np.diff(per) > 0)


def test_power_level_hides_a_power_law_of_the_storage_part():
    c = synthetic_laws.generate("power_level", np.random.default_rng(5))
    w = 2 * np.pi * c.frequency_hz
    storage = (1 / c.clean_values + c.mass * w**2).real
    base = (1 / c.base_values + c.mass * w**2).real
    ratio = (storage / base).reshape(5, -1)
    np.testing.assert_allclose(ratio, ratio[:, :1] * np.ones_like(ratio), rtol=1e-9)
    p = c.parameters
    u = np.asarray(synthetic_laws.FRF_LEVELS_N) / synthetic_laws.A_TOP
    expected = (1 + p["d"] * u ** p["exponent"]) / (1 + p["d"] * u[2] ** p["exponent"])
    np.testing.assert_allclose(ratio[:, 0], expected, rtol=1e-9)


def test_a_joint_that_slips_lowers_one_mode_from_one_level_on():
    c = synthetic_laws.generate("structure_joint_slip", np.random.default_rng(2))
    p = c.parameters
    assert 0.03 <= p["stiffness_drop"] <= 0.1 and p["slip_from_level"] in synthetic_laws.LEVELS_N


def test_unknown_case_is_refused():
    with pytest.raises(ValueError, match="case must be one of"):
        synthetic_laws.generate("cubic", np.random.default_rng(0))


def test_power_law_of_a_mount_named_with_its_exponent_via_the_cli(tmp_path, capsys):
    """The issue's hardening/softening spring: the storage part changes as a power of the
    level; the log law of the library stops short, the law from the per-condition fits
    reaches them."""
    path = tmp_path / "mount.csv"
    assert cli.main(["discrepancy", "synth", "--effect", "power_level", "--seed", "5",
                     "--out", str(path), "--json"]) == 0
    truth = json.loads(capsys.readouterr().out)["hidden_parameters"]
    assert cli.main(["discrepancy", "frf", str(path), "--quantity", "receptance",
                     "--covariates", "excitation_n", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    v = out["verdict"]
    assert (v["status"], v["effect"], v["form"]) == ("explained", "amplitude_dependence",
                                                     "law")
    law = {p["coordinate"]: p for p in out["augmented"]["law"]["laws"]}
    assert law["storage"]["law"] == "power_change"
    e = law["storage"]["parameters"][1]
    assert e["value"] == pytest.approx(truth["exponent"], abs=max(4 * e["std"], 0.05))
    assert "storage change ~ excitation_n^(" in out["augmented"]["law"]["text"]
    # the moving coordinates and the laws they were scored with are in the report
    storage = next(t for t in out["trends"] if t["coordinate"] == "storage")
    assert storage["moving"] and storage["p_value"] < 1e-3
    assert {x["law"] for x in storage["laws"]} >= {"linear", "power", "logarithmic", "free"}
    # ... and the law reaches what the per-condition fits reach, the log law does not
    base, ref = out["baseline"]["error"], out["saturated_reference"]["error"]
    assert (base - out["final"]["error"]) >= 0.9 * (base - ref)
    log_law = next(c for c in out["candidates"] if c["form"] == "logarithmic"
                   and c["effect"] == "amplitude_dependence")
    assert (base - log_law["error"]) < 0.9 * (base - ref)
    # a law case takes no --system
    assert cli.main(["discrepancy", "synth", "--effect", "power_level", "--seed", "5",
                     "--out", str(path), "--system", "4.1-A"]) == 2
    assert "--system" in capsys.readouterr().err


def modal_result(case, seed, n_points):
    c = synthetic_laws.generate(case, np.random.default_rng(seed), n_points=n_points)
    rec = to_receptance(c.frequency_hz, c.values, c.quantity)
    conds = split_conditions(c.frequency_hz, rec, "receptance", c.covariates,
                             list(c.condition_columns))
    return c, loop.run(ModalDomain(conds, quantity=c.quantity, covariates=["excitation_n"],
                                   max_modes=4))


def test_power_laws_of_several_modes_at_once():
    c, res = modal_result("structure_power_level", 2, 160)
    v = res.verdict
    assert (v.status, v.effect, v.label) == ("explained", "amplitude_dependence",
                                             "excitation_n, law")
    step = res.steps[0]
    parts = {p.coordinate: p for p in step.fit.law.parts}
    est = {e.name: e for e in step.fit.estimates}
    for m in c.parameters["modes"]:  # every hidden mode's stiffness, by a power law
        part = parts[f"mode {m['mode']} stiffness"]
        if part.law == "power_change":
            e = est[part.names[1]]
            assert e.value == pytest.approx(m["exponent"], abs=max(4 * e.std, 0.1))
    stiff = [p for p in parts if p.endswith("stiffness")]
    assert len(stiff) == len(c.parameters["modes"])  # and no other mode's
    assert recovery(res) >= 0.9
    text = "\n".join(discrepancy_cli._summary_lines(res))
    assert "law: amplitude_dependence (excitation_n): mode" in text
    assert "per-condition parameters moving beyond their errors: " in text


def test_replicate_sweeps_name_nothing():
    c, res = modal_result("structure_replicates", 4, 160)
    assert res.verdict.status in ("consistent", "no_covariate_effect")
    assert not res.steps and not any(t.moving for t in res.trends)
    law = next(x for x in res.candidates if x.label == "excitation_n, law")
    assert not law.applicable and "moves with excitation_n" in law.reason
