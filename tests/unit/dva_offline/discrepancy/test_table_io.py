"""Reading an instrument's export as written: column names, units row, sweeps by set or tolerance.

Uses the measured DMA export shipped in tests/data/discrepancy (see its README).
"""
from pathlib import Path

import numpy as np
import pytest

from dva_offline import cli
from dva_offline.discrepancy import table_io

DATA = Path(__file__).resolve().parents[3] / "data" / "discrepancy"
DMA = DATA / "dma_tension_raw.csv"
DMA_COLUMNS = "f=f,real=E_stor,imag=E_loss,temperature_c=T"


def read(**kw):
    table = table_io.read_table(DMA)
    return table_io.conditions_from_table(table, "modulus",
                                          table_io.ColumnMap.parse(DMA_COLUMNS), **kw)


def test_units_row_and_byte_order_mark_are_read():
    table = table_io.read_table(DMA)
    assert list(table.columns) == ["f", "E_stor", "E_loss", "T", "Set"]  # no BOM in 'f'
    assert table.units["E_stor"] == "MPa" and table.n_rows == 210


def test_group_by_set_keeps_the_measured_temperature_per_point():
    conditions, grouping, info = read(group_by="Set")
    assert len(conditions) == 21 and all(c.frequency_hz.size == 10 for c in conditions)
    assert info["units"]["real"].startswith("MPa")
    # E' at -50 C, 0.1 Hz: 8097.18 MPa in the file -> Pa
    assert conditions[0].values[0].real == pytest.approx(8097.175545e6)
    spread = [np.ptp(c.covariates["temperature_c"]) for c in conditions]
    assert max(spread) > 0.1  # the drift within a sweep is kept, not averaged away
    assert "Set" in grouping.method


def test_tolerance_grouping_equals_the_set_column():
    by_set, _, _ = read(group_by="Set")
    by_tol, grouping, _ = read(tolerance=1.0, covariates=["temperature_c"])
    assert len(by_tol) == 21 and "within 1" in grouping.method
    for a, b in zip(by_set, by_tol):
        np.testing.assert_array_equal(a.values, b.values)


def test_exact_grouping_of_a_drifting_temperature_names_the_fix():
    table = table_io.read_table(DMA)
    cmap = table_io.ColumnMap.parse("f=f,real=E_stor,imag=E_loss")
    labels, grouping = table_io.group_rows({"T": table.columns["T"]}, 210, columns=["T"])
    assert grouping.n_conditions > 150  # every sweep split
    with pytest.raises(ValueError, match="--group-by"):
        table_io.conditions_from_table(
            table_io.Table({k: v for k, v in table.columns.items() if k != "Set"},
                           table.units, 210), "modulus", cmap)


def test_unit_flag_contradicting_the_units_row_is_refused():
    with pytest.raises(ValueError, match="units row says 'MPa'"):
        read(group_by="Set", value_unit="GPa")
    conditions, _, info = read(group_by="Set", value_unit="MPa")
    assert info["units"]["real"] == "MPa (flag)"


def test_cli_errors_are_one_line_exit_2(capsys):
    code = cli.main(["discrepancy", "frf", str(DMA), "--quantity", "modulus"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "missing column" in err and "--columns" in err and "\n" not in err
    code = cli.main(["discrepancy", "frf", str(DMA), "--quantity", "modulus", "--columns",
                     DMA_COLUMNS, "--value-unit", "psi", "--group-by", "Set"])
    assert code == 2 and "unknown modulus value unit 'psi'" in capsys.readouterr().err


def test_semicolons_rad_per_s_and_n_per_mm_flags(tmp_path):
    w = 2 * np.pi * np.geomspace(1, 100, 12)
    rows = ["omega;K_re;K_im;temp"] + [f"{x};{2.0 + 0.01 * i};{0.5};{20 + 0.01 * i}"
                                      for i, x in enumerate(w)]
    path = tmp_path / "export.csv"
    path.write_text("\n".join(rows) + "\n")
    table = table_io.read_table(path)
    conds, grouping, info = table_io.conditions_from_table(
        table, "stiffness", table_io.ColumnMap.parse("f=omega,re=K_re,im=K_im"),
        frequency_unit="rad/s", value_unit="N/mm", tolerance=0.5)
    assert len(conds) == 1 and grouping.n_conditions == 1
    np.testing.assert_allclose(conds[0].frequency_hz, np.geomspace(1, 100, 12))
    assert conds[0].values[0] == pytest.approx(2000.0 + 500.0j)
    assert info["units"]["frequency"] == "rad/s (flag)"


def text_column_export(tmp_path):
    """Two sweeps of a modulus with a text column naming each raw file."""
    rows = ["f,E1,E2,T,raw_file,set"]
    for k, (temp, name) in enumerate(((20.0, "run_a.txt"), (40.0, "run b.txt"))):
        rows += [f"{x},{1e6 * (1 + 0.1 * k) * x ** 0.1},{2e5},{temp + 0.01 * i},{name},{k}"
                 for i, x in enumerate(np.geomspace(0.1, 100, 12))]
    path = tmp_path / "export.csv"
    path.write_text("\n".join(rows) + "\n")
    return path


def test_a_text_column_nobody_selects_is_ignored(tmp_path):
    path = text_column_export(tmp_path)
    table = table_io.read_table(path)
    assert "raw_file" not in table.columns and table.text["raw_file"][0] == "run_a.txt"
    cmap = table_io.ColumnMap.parse("f=f,real=E1,imag=E2,temperature_c=T")
    conds, grouping, info = table_io.conditions_from_table(table, "modulus", cmap,
                                                           group_by="set")
    assert grouping.n_conditions == 2 and info["ignored_text_columns"] == ["raw_file"]
    assert set(conds[0].covariates) == {"temperature_c", "set"}
    # grouped by the text column itself: the same two sweeps
    by_name, grouping, info = table_io.conditions_from_table(table, "modulus", cmap,
                                                             group_by="raw_file")
    assert grouping.n_conditions == 2 and info["ignored_text_columns"] == []
    np.testing.assert_array_equal(by_name[1].values, conds[1].values)
    # selected as a covariate or a role, it is refused with its first text cell
    with pytest.raises(ValueError, match=r"line 2, column 'raw_file': 'run_a.txt' is not a"):
        table_io.conditions_from_table(table, "modulus", cmap, covariates=["raw_file"])
    with pytest.raises(ValueError, match="column 'raw_file'"):
        table_io.conditions_from_table(table, "modulus", table_io.ColumnMap.parse(
            "f=f,real=raw_file,imag=E2"))


def test_cli_reads_past_a_text_column(tmp_path, capsys):
    path = text_column_export(tmp_path)
    code = cli.main(["discrepancy", "frf", str(path), "--quantity", "modulus", "--columns",
                     "f=f,real=E1,imag=E2,temperature_c=T", "--group-by", "set",
                     "--max-steps", "1", "--json"])
    assert code == 0
    import json

    out = json.loads(capsys.readouterr().out)
    assert out["input"]["ignored_text_columns"] == ["raw_file"]
    assert out["grouping"]["n_conditions"] == 2
