"""File input/output for the isolator tools: FRF CSV, time-series CSV, load-deflection CSV, UFF 58.

Formats (SI units, one header row, comma separated):

* FRF CSV: ``frequency_hz,real,imag`` plus any extra columns, kept by name as covariates
  (e.g. ``excitation_n``, ``temperature_c``). The quantity (receptance [m/N], accelerance
  [(m/s^2)/N] or complex stiffness [N/m]) is given by the caller.
* Time-series CSV: ``time_s`` (optional if the sampling rate is given), a force column
  (default ``force_n``) and one or more response columns (default: all other columns).
* Load-deflection CSV: ``deflection_m,load_n``.
* Universal file format dataset 58 (function at one response/reference pair), read with pyuff
  (optional dependency, imported only when used).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dva_offline.isolator.frf_data import FrfData

FRF_COLUMNS = ("frequency_hz", "real", "imag")


def _read_table(path) -> tuple[list[str], np.ndarray]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    with path.open(newline="") as fh:
        rows = [row for row in csv.reader(fh) if row and not row[0].lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path}: file is empty")
    header = [name.strip() for name in rows[0]]
    if len(set(header)) != len(header):
        raise ValueError(f"{path}: duplicate column names in header {header}")
    data = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ValueError(
                f"{path}: line {i + 2} has {len(row)} values, header has {len(header)}"
            )
        for j, cell in enumerate(row):
            try:
                data[i, j] = float(cell)
            except ValueError:
                raise ValueError(
                    f"{path}: line {i + 2}, column {header[j]!r}: {cell!r} is not a number"
                ) from None
    return header, data


def _require(path, header, names):
    missing = [n for n in names if n not in header]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}; found {header}")


def _check_finite(path, header, data, names):
    for name in names:
        col = data[:, header.index(name)]
        bad = np.nonzero(~np.isfinite(col))[0]
        if bad.size:
            raise ValueError(f"{path}: column {name!r} is NaN at line {bad[0] + 2}")


def read_frf_csv(path, quantity: str) -> FrfData:
    """Read an FRF CSV (see module docstring); validation errors name the file and problem."""
    header, data = _read_table(path)
    _require(path, header, FRF_COLUMNS)
    _check_finite(path, header, data, FRF_COLUMNS)
    cols = {name: data[:, i] for i, name in enumerate(header)}
    covariates = {n: v for n, v in cols.items() if n not in FRF_COLUMNS}
    try:
        return FrfData(
            cols["frequency_hz"], cols["real"] + 1j * cols["imag"], quantity, covariates
        )
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def write_frf_csv(path, frequency_hz, values, covariates: dict | None = None) -> None:
    """Write ``frequency_hz,real,imag`` plus extra columns (e.g. coherence)."""
    f = np.asarray(frequency_hz, dtype=float)
    v = np.asarray(values, dtype=complex)
    extra = covariates or {}
    header = list(FRF_COLUMNS) + list(extra)
    cols = [f, v.real, v.imag] + [np.asarray(c, dtype=float) for c in extra.values()]
    with Path(path).open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in zip(*cols):
            writer.writerow([repr(float(x)) for x in row])


@dataclass(frozen=True)
class TimeSeries:
    """Force and response records.

    Attributes
    ----------
    fs : float
        Sampling rate [Hz].
    force : numpy.ndarray
        Shape (T,) [N].
    response : numpy.ndarray
        Shape (C, T) (channels first, time last).
    response_names : tuple of str
    """

    fs: float
    force: np.ndarray
    response: np.ndarray
    response_names: tuple[str, ...]


def read_time_series_csv(
    path,
    force_column: str = "force_n",
    response_columns: list[str] | None = None,
    fs: float | None = None,
) -> TimeSeries:
    """Read a time-series CSV; the sampling rate comes from ``time_s`` unless ``fs`` is given."""
    header, data = _read_table(path)
    _require(path, header, [force_column])
    if response_columns is None:
        response_columns = [n for n in header if n not in (force_column, "time_s")]
        if not response_columns:
            raise ValueError(f"{path}: no response columns besides {force_column!r}")
    _require(path, header, response_columns)
    _check_finite(path, header, data, [force_column, *response_columns])
    if fs is None:
        if "time_s" not in header:
            raise ValueError(f"{path}: no 'time_s' column; give the sampling rate (--fs)")
        t = data[:, header.index("time_s")]
        dt = np.diff(t)
        if dt.size == 0 or np.any(dt <= 0):
            raise ValueError(f"{path}: 'time_s' must be strictly increasing")
        if np.ptp(dt) > 1e-6 * np.mean(dt):
            raise ValueError(f"{path}: 'time_s' is not uniformly sampled")
        fs = 1.0 / float(np.mean(dt))
    response = np.vstack([data[:, header.index(n)] for n in response_columns])
    return TimeSeries(float(fs), data[:, header.index(force_column)], response,
                      tuple(response_columns))


def read_load_deflection_csv(path) -> tuple[np.ndarray, np.ndarray]:
    """Read ``deflection_m,load_n``; returns (deflection [m], load [N]), shapes (P,)."""
    header, data = _read_table(path)
    _require(path, header, ["deflection_m", "load_n"])
    _check_finite(path, header, data, ["deflection_m", "load_n"])
    return data[:, header.index("deflection_m")], data[:, header.index("load_n")]


def read_uff58(path, quantity: str, index: int = 0) -> FrfData:
    """Read the ``index``-th dataset 58 of a universal file (abscissa in Hz, complex ordinate)."""
    try:
        import pyuff  # optional dependency
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ValueError("reading UFF files needs the 'pyuff' package") from exc
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    uff = pyuff.UFF(str(path))
    sets = [i for i, t in enumerate(uff.get_set_types()) if int(t) == 58]
    if len(sets) <= index:
        raise ValueError(f"{path}: has {len(sets)} dataset(s) 58, asked for number {index}")
    ds = uff.read_sets(sets[index])
    values = np.asarray(ds["data"])
    if not np.iscomplexobj(values):
        raise ValueError(f"{path}: dataset 58 number {index} is real, expected a complex FRF")
    try:
        return FrfData(np.asarray(ds["x"], dtype=float), values, quantity)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
