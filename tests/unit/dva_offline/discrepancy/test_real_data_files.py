"""The public measured data sets in tests/data/discrepancy/real/ read as their README says.

Each file goes through the tool's own reader (table_io) with the README's column map and
grouping, and the property its expected verdict rests on is checked on the data directly,
without a model: repeated hits that agree, a jointed beam whose resonance peak drops with the
level, a melt that softens as it warms. The loop's verdicts on these files are tested by the
discrepancy loop's own tests.
"""
from pathlib import Path

import numpy as np
import pytest

from dva_offline.discrepancy import table_io

REAL = Path(__file__).resolve().parents[3] / "data" / "discrepancy" / "real"
README = (REAL / "README.md").read_text(encoding="utf-8")


def sweeps(name, quantity, columns=None, group_by=None, covariates=None):
    table = table_io.read_table(REAL / name)
    conditions, grouping, _ = table_io.conditions_from_table(
        table, quantity, table_io.ColumnMap.parse(columns), group_by=group_by,
        covariates=covariates)
    return conditions, grouping


def peak_hz(sweep, lo, hi):
    """Frequency of the largest |H| in [lo, hi] Hz, refined by a parabola through log|H|."""
    f, mag = sweep.frequency_hz, np.log(np.abs(sweep.values))
    k = np.flatnonzero((f >= lo) & (f <= hi))
    i = k[np.argmax(mag[k])]
    y0, y1, y2 = mag[i - 1:i + 2]
    return f[i] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * (f[i + 1] - f[i])


@pytest.mark.parametrize("name", sorted(p.name for p in REAL.glob("*.csv")))
def test_each_file_is_documented_small_and_licensed(name):
    assert f"`{name}`" in README
    assert (REAL / name).stat().st_size < 2_000_000


def test_every_conversion_script_and_licence_is_named_in_the_readme():
    extras = list(REAL.glob("convert_*.py")) + list(REAL.glob("LICENSE.*"))
    assert len(extras) >= 4
    assert all(f"`{p.name}`" in README for p in extras)


def test_hammer_hits_agree_whatever_the_force():
    hits, grouping = sweeps("impact_hits_pyfrf.csv", "accelerance", group_by="hit",
                            covariates=["force_peak_n"])
    assert grouping.n_conditions == 5 and all(h.frequency_hz.size == 101 for h in hits)
    force = [h.covariates["force_peak_n"][0] for h in hits]
    assert max(force) / min(force) > 1.25  # the level varies ...
    for lo, hi in ((800, 820), (845, 860), (890, 910)):
        peaks = [peak_hz(h, lo, hi) for h in hits]
        assert np.ptp(peaks) < 0.2  # ... and the resonances do not move (2 Hz lines)


def test_jointed_beam_peak_drops_with_the_response_level():
    levels, grouping = sweeps("brb_response_control.csv", "accelerance", group_by="level",
                              covariates=["response_amplitude_ms2"])
    assert grouping.n_conditions == 8
    amplitude = [np.mean(s.covariates["response_amplitude_ms2"]) for s in levels]
    assert np.all(np.diff(amplitude) > 0)
    peak = [np.max(np.abs(s.values)) for s in levels]
    assert np.all(np.diff(peak) < 0) and peak[0] / peak[-1] > 3  # damping grows with level
    centre = [peak_hz(s, 79.5, 81.0) for s in levels]
    assert np.ptp(centre) < 0.5  # the frequency moves little (0.5 % of 80 Hz)


def test_jointed_beam_force_controlled_sweeps():
    levels, grouping = sweeps("brb_force_control.csv", "accelerance", group_by="level",
                              covariates=["force_n"])
    assert grouping.n_conditions == 4
    force = [np.mean(s.covariates["force_n"]) for s in levels]
    assert np.all(np.diff(force) > 0)
    peak = [np.max(np.abs(s.values)) for s in levels]
    assert np.all(np.diff(peak) < 0)


def test_melt_softens_as_it_warms_and_reads_in_si():
    temps, grouping = sweeps("pi88k_melt_reptate.csv", "modulus",
                             columns="f=omega,real=G_stor,imag=G_loss,temperature_c=T",
                             group_by="set")
    assert grouping.n_conditions == 8
    nominal = [np.mean(s.covariates["temperature_c"]) for s in temps]
    np.testing.assert_allclose(sorted(nominal), [-45, -40, -30, -20, -10, 0, 10, 25], atol=0.05)
    order = np.argsort(nominal)
    # 100 rad/s read from the units row: 15.9 Hz, the top of every sweep
    assert all(s.frequency_hz.max() == pytest.approx(100 / (2 * np.pi)) for s in temps)
    top = [abs(temps[i].values[np.argmax(temps[i].frequency_hz)]) for i in order]
    assert np.all(np.diff(top) < 0)  # |G*| at 100 rad/s falls with temperature
    assert top[0] > 1e6  # Pa, not MPa
