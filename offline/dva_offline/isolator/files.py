"""File input/output for the isolator tools: FRF CSV, time-series CSV, load-deflection CSV, UFF 58.

Formats (SI units, UTF-8, one header row, comma separated, at most :data:`MAX_ROWS` data rows):

* FRF CSV: ``frequency_hz,real,imag`` plus any extra columns, kept by name as covariates
  (e.g. ``excitation_n``, ``temperature_c``). The quantity (receptance [m/N], accelerance
  [(m/s^2)/N] or complex stiffness [N/m]) is given by the caller.
* Time-series CSV: ``time_s`` (optional if the sampling rate is given), a force column
  (default ``force_n``) and one or more response columns (default: all other columns).
* Stepped-sine CSV, one row per excitation frequency: ``frequency_hz`` and either
  ``real,imag`` (the FRF at each step, as an analyser reports it) or
  ``force_amplitude_n,force_phase_deg,response_amplitude,response_phase_deg`` (force
  F cos(w t + phi_f) and response X cos(w t + phi_x); ``*_phase_rad`` columns are accepted
  instead of ``*_phase_deg``; amplitudes both peak or both RMS). With amplitudes and phases the
  response is displacement [m] (receptance) or acceleration [m/s^2] (accelerance). Other
  columns are kept as covariates.
* Load-deflection CSV: ``deflection_m,load_n``.
* Universal file format dataset 58 (function at one response/reference pair), read with pyuff
  (optional dependency ``pip install 'dva-offline[uff]'``, imported only when used).

A complex modulus (``--quantity modulus`` in the CLI) is an FRF CSV whose ``real,imag`` are the
storage and loss modulus E', E'' [Pa]; it is read as quantity ``stiffness`` and scaled to N/m
by :func:`~dva_offline.isolator.frf_data.modulus_to_stiffness`.
"""
from __future__ import annotations

import csv
import sys
from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.atomic_io import atomic_output
from dva_offline.isolator.frf_data import (
    FrfData,
    condition_columns,
    frf_from_amplitude_phase,
    split_conditions,
)

FRF_COLUMNS = ("frequency_hz", "real", "imag")
#: Most data rows read from one CSV file (16 min of a time series at 1 kHz; an FRF has a few
#: thousand points); a larger file is refused after this many rows, not read to its end.
MAX_ROWS = 1_000_000
#: Most points of one FRF table (an analyser gives a few thousand lines, at most 25,600): an
#: identification or discrepancy fit holds a few Jacobians of this many rows, so the limit
#: bounds its memory (docs/reliability.md).
MAX_FRF_POINTS = 100_000
#: Tables of more points than this are announced before the fit (it takes a while).
LARGE_FRF_POINTS = 10_000
#: [bytes] largest universal file read (an ASCII dataset 58 takes about 40 bytes a point).
MAX_UFF_BYTES = 64 * 2**20
STEP_AMPLITUDES = ("force_amplitude_n", "response_amplitude")
STEP_PHASES = ("force_phase", "response_phase")


def say_large_table(path, n_points: int) -> None:
    """A line on stderr before a long fit: the user sees why nothing else is said for a while."""
    if n_points > LARGE_FRF_POINTS:
        print(f"read {n_points:,} points of {path}; a fit of this many takes minutes (at most "
              f"{MAX_FRF_POINTS:,} are read)", file=sys.stderr, flush=True)


def append_numeric_row(values: array, row: list[str], header: list[str], path, line: int,
                       rows: int, max_rows: int = MAX_ROWS) -> None:
    """Append the data row ``row`` (line ``line`` of ``path``; ``rows`` read before it) to
    ``values`` as floats: one value per header column, at most ``max_rows`` rows (a
    runaway file is refused there, not read to its end); errors name the file, line and
    column."""
    if len(row) != len(header):
        raise ValueError(f"{path}: line {line} has {len(row)} values, header has {len(header)}")
    if rows == max_rows:
        kind = "FRF points" if max_rows == MAX_FRF_POINTS else "data rows"
        raise ValueError(f"{path}: more than {max_rows:,} {kind}; at most that many are read "
                         "(decimate or split the file)")
    for name, cell in zip(header, row):
        try:
            values.append(float(cell))
        except ValueError:
            raise ValueError(f"{path}: line {line}, column {name!r}: {cell[:40]!r} is not a "
                             "number") from None


def _read_table(path, max_rows: int = MAX_ROWS) -> tuple[list[str], np.ndarray]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    header: list[str] | None = None
    values = array("d")  # flat, row after row: 8 bytes a value, not a Python list of rows
    rows = 0
    reader = None
    try:
        with path.open(encoding="utf-8", newline="") as fh:
            reader = csv.reader(fh)
            for row in reader:
                if not row or row[0].lstrip().startswith("#"):
                    continue
                if header is None:
                    header = [name.strip() for name in row]
                    if len(set(header)) != len(header):
                        raise ValueError(f"{path}: duplicate column names in header {header}")
                    continue
                append_numeric_row(values, row, header, path, reader.line_num, rows, max_rows)
                rows += 1
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text (byte at offset {exc.start}); a CSV file "
                         "is expected") from None
    except csv.Error as exc:  # e.g. NUL bytes: a binary file
        line = reader.line_num if reader is not None else 0
        raise ValueError(f"{path}: line {line} is not CSV text ({exc})") from None
    if header is None:
        raise ValueError(f"{path}: file is empty")
    return header, np.frombuffer(values, dtype=float).reshape(rows, len(header)).copy()


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


def _check_increasing(path, header, data, name="frequency_hz"):
    col = data[:, header.index(name)]
    steps = np.nonzero(np.diff(col) <= 0)[0]
    if steps.size:
        i = steps[0]
        raise ValueError(
            f"{path}: {name} must be strictly increasing: line {i + 3} ({col[i + 1]:g} Hz) "
            f"follows line {i + 2} ({col[i]:g} Hz)"
        )


def read_frf_csv(path, quantity: str) -> FrfData:
    """Read an FRF CSV (see module docstring); validation errors name the file and problem."""
    header, data = _read_table(path, MAX_FRF_POINTS)
    _require(path, header, FRF_COLUMNS)
    _check_finite(path, header, data, FRF_COLUMNS)
    _check_increasing(path, header, data)
    cols = {name: data[:, i] for i, name in enumerate(header)}
    covariates = {n: v for n, v in cols.items() if n not in FRF_COLUMNS}
    try:
        return FrfData(
            cols["frequency_hz"], cols["real"] + 1j * cols["imag"], quantity, covariates
        )
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def read_frf_csv_conditions(path, quantity: str, columns=None) -> list[FrfData]:
    """Read an FRF CSV holding one or several sweeps stacked by condition.

    Rows with equal values in the condition ``columns`` form one sweep (strictly increasing
    frequency within it). Default columns: every covariate with few distinct values
    (:func:`~dva_offline.isolator.frf_data.condition_columns`), so a per-point ``coherence``
    column is kept as data but does not split the rows.

    Returns
    -------
    list of FrfData
        One per condition, in order of first appearance in the file.
    """
    header, data = _read_table(path, MAX_FRF_POINTS)
    _require(path, header, FRF_COLUMNS)
    _check_finite(path, header, data, FRF_COLUMNS)
    cols = {name: data[:, i] for i, name in enumerate(header)}
    covariates = {n: v for n, v in cols.items() if n not in FRF_COLUMNS}
    if columns is None:
        columns = condition_columns(covariates, data.shape[0])
    else:
        _require(path, header, list(columns))
        _check_finite(path, header, data, list(columns))
    try:
        return split_conditions(
            cols["frequency_hz"], cols["real"] + 1j * cols["imag"], quantity, covariates,
            list(columns),
        )
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def read_stepped_sine_csv(path, quantity: str) -> FrfData:
    """Read a stepped-sine CSV (see module docstring) as an FRF of ``quantity``.

    ``real,imag`` files may hold any quantity; amplitude/phase files hold response/force, so
    ``quantity`` must be ``receptance`` or ``accelerance``.
    """
    header, data = _read_table(path, MAX_FRF_POINTS)
    _require(path, header, ["frequency_hz"])
    if "real" in header or "imag" in header:
        return read_frf_csv(path, quantity)
    phases = []
    for stem in STEP_PHASES:
        found = [n for n in (f"{stem}_deg", f"{stem}_rad") if n in header]
        if len(found) == 2:
            raise ValueError(f"{path}: give {stem}_deg or {stem}_rad, not both")
        phases.append(found[0] if found else f"{stem}_deg")
    needed = ["frequency_hz", STEP_AMPLITUDES[0], phases[0], STEP_AMPLITUDES[1], phases[1]]
    missing = [n for n in needed if n not in header]
    if missing:
        raise ValueError(
            f"{path}: stepped-sine file needs columns frequency_hz plus real,imag or "
            f"{','.join(needed[1:])}; missing {missing}; found {header}"
        )
    if quantity not in ("receptance", "accelerance"):
        raise ValueError(
            f"{path}: amplitude/phase steps give response/force; use --quantity receptance "
            f"(response in m) or accelerance (response in m/s^2), not {quantity!r}"
        )
    _check_finite(path, header, data, needed)
    _check_increasing(path, header, data)
    col = {name: data[:, i] for i, name in enumerate(header)}
    for name in STEP_AMPLITUDES:
        bad = np.nonzero(~(col[name] > 0))[0]
        if bad.size:
            raise ValueError(
                f"{path}: column {name!r} must be > 0, got {col[name][bad[0]]:g} at line "
                f"{bad[0] + 2}"
            )
    f_phase, r_phase = (
        np.radians(col[n]) if n.endswith("_deg") else col[n] for n in phases
    )
    h = frf_from_amplitude_phase(col[STEP_AMPLITUDES[0]], f_phase, col[STEP_AMPLITUDES[1]],
                                 r_phase)
    covariates = {n: v for n, v in col.items() if n not in needed}
    try:
        return FrfData(col["frequency_hz"], h, quantity, covariates)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def write_stepped_sine_csv(path, frequency_hz, force, response, covariates=None) -> None:
    """Write a stepped-sine CSV in amplitude/phase form from complex force and response phasors.

    Parameters
    ----------
    frequency_hz : array_like, shape (N,)
    force, response : array_like, shape (N,), complex
        Phasors F exp(j phi_f) [N] and X exp(j phi_x) [m or m/s^2] of each step.
    """
    f = np.asarray(frequency_hz, dtype=float)
    fc = np.asarray(force, dtype=complex)
    rc = np.asarray(response, dtype=complex)
    extra = covariates or {}
    header = ["frequency_hz", "force_amplitude_n", "force_phase_deg", "response_amplitude",
              "response_phase_deg", *extra]
    cols = [f, np.abs(fc), np.degrees(np.angle(fc)), np.abs(rc), np.degrees(np.angle(rc))]
    cols += [np.asarray(c, dtype=float) for c in extra.values()]
    with atomic_output(path) as fh:  # never half a file, even if interrupted
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in zip(*cols):
            writer.writerow([repr(float(x)) for x in row])


def write_frf_csv(path, frequency_hz, values, covariates: dict | None = None) -> None:
    """Write ``frequency_hz,real,imag`` plus extra columns (e.g. coherence)."""
    f = np.asarray(frequency_hz, dtype=float)
    v = np.asarray(values, dtype=complex)
    extra = covariates or {}
    header = list(FRF_COLUMNS) + list(extra)
    cols = [f, v.real, v.imag] + [np.asarray(c, dtype=float) for c in extra.values()]
    with atomic_output(path) as fh:  # never half a file, even if interrupted
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
    except ImportError:
        raise ValueError(
            f"{path}: reading universal files (UFF 58) needs the optional package pyuff; "
            "install it with: pip install 'dva-offline[uff]'  (or: pip install 'pyuff>=2.4')"
        ) from None
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    size = path.stat().st_size
    if size > MAX_UFF_BYTES:
        raise ValueError(f"{path}: {size / 2**20:.0f} MiB; at most {MAX_UFF_BYTES // 2**20} MiB "
                         "of universal file are read")
    try:
        uff = pyuff.UFF(str(path))
        sets = [i for i, t in enumerate(uff.get_set_types()) if int(t) == 58]
        ds = uff.read_sets(sets[index]) if len(sets) > index else None
    except Exception as exc:  # pyuff fails on damaged files in many ways, none of them ours
        detail = " ".join(f"{type(exc).__name__}: {exc}".split())[:160]
        raise ValueError(f"{path}: not a readable universal file ({detail})") from None
    if ds is None:
        raise ValueError(f"{path}: has {len(sets)} dataset(s) 58, asked for number {index}")
    values = np.asarray(ds.get("data", []))
    if values.size > MAX_FRF_POINTS:
        raise ValueError(f"{path}: {values.size:,} points; at most {MAX_FRF_POINTS:,} FRF "
                         "points are read")
    if not np.iscomplexobj(values):
        raise ValueError(f"{path}: dataset 58 number {index} is real, expected a complex FRF")
    try:
        return FrfData(np.asarray(ds.get("x", []), dtype=float), values, quantity)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


#: UFF 58 ordinate data types (record 9 field 1: 12 acceleration, 8 displacement, 13 force).
_UFF_ORDINATE = {"receptance": 8, "accelerance": 12}


def write_uff58(path, frequency_hz, values, quantity: str) -> None:
    """Write one FRF as a universal file dataset 58 (needs the optional pyuff).

    Parameters
    ----------
    path : str or Path
        Output ``.uff`` file (overwritten).
    frequency_hz : array_like, shape (N,)
        Evenly or unevenly spaced frequencies [Hz].
    values : array_like, shape (N,)
        Complex FRF [SI units of ``quantity``].
    quantity : {"receptance", "accelerance"}
    """
    try:
        import pyuff  # optional dependency
    except ImportError:
        raise ValueError(
            f"{path}: writing universal files (UFF 58) needs the optional package pyuff; "
            "install it with: pip install 'dva-offline[uff]'"
        ) from None
    if quantity not in _UFF_ORDINATE:
        raise ValueError(f"quantity must be one of {tuple(_UFF_ORDINATE)}, got {quantity!r}")
    f = np.asarray(frequency_hz, dtype=float)
    d = np.diff(f)
    even = bool(np.allclose(d, d[0], rtol=1e-9))
    ds = pyuff.prepare_58(
        func_type=4, rsp_node=1, rsp_dir=3, ref_node=1, ref_dir=3,
        data=np.asarray(values, dtype=complex), x=f, id1=quantity, rsp_ent_name="mass",
        ref_ent_name="mass", abscissa_spacing=1 if even else 0,
        ordinate_spec_data_type=_UFF_ORDINATE[quantity], orddenom_spec_data_type=13,
    )
    pyuff.UFF(str(path)).write_sets(ds, mode="overwrite")
