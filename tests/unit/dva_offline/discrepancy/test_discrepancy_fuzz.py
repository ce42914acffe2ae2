"""Random real-scale tables through ``dva discrepancy frf`` and ``modal``: every run ends with
a verdict or a one-line input error naming the file, never an internal exception.

The CI share of the fuzz (a fixed seed, four tables, one step each); the 200-table run is
``bench/bench_discrepancy_fuzz.py`` (docs/discrepancy.md, "Fuzz").
"""
import numpy as np
import pytest

from dva_offline.discrepancy.fuzz_run import commands, run_table
from dva_offline.discrepancy.fuzz_tables import KINDS, random_table

SEED = 17
N_TABLES = 4  # the suite's share; the 200-table run is bench/bench_discrepancy_fuzz.py


def test_tables_have_real_scales():
    rng = np.random.default_rng(SEED)
    tables = [random_table(rng, kind) for kind in KINDS for _ in range(5)]
    for t in tables:
        assert 0.01 <= t.frequency_hz.min() and t.frequency_hz.max() <= 1e4
        assert np.all(np.isfinite(t.values))
    moduli = np.concatenate([np.abs(t.values) for t in tables if t.quantity == "modulus"])
    assert moduli.max() > 1e6 and moduli.max() <= 2e10
    with pytest.raises(ValueError, match="kind must be one of"):
        random_table(rng, "voltage")


def test_fuzz_every_run_ends_with_a_verdict_or_an_input_error(tmp_path):
    rng = np.random.default_rng(SEED)
    outcomes = []
    for i in range(N_TABLES):
        table = random_table(rng)
        for command in commands(table):
            outcome, detail = run_table(table, tmp_path / f"t{i}.csv", command,
                                        ("--max-steps", "1"))
            outcomes.append((i, table.quantity, command, outcome, detail))
    internal = [o for o in outcomes if o[3] == "internal"]
    assert not internal, internal
    assert sum(o[3] == "verdict" for o in outcomes) >= N_TABLES // 2
