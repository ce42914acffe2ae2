"""Reading an instrument's frequency-response export as it is: column names, units, sweeps.

A CSV (comma, semicolon or tab separated; a UTF-8 byte-order mark is ignored) with one header
row, optionally a units row right below it (a row without any number, e.g. ``Hz, MPa, MPa, C,
-``) and one row per measured point. A column with text in it (a file name, a sample label) is
ignored unless selected: as a set column to group by it works, as a covariate or a value it
is refused naming its first cell that is no number. :class:`ColumnMap` says which columns
hold the frequency and the real and imaginary parts (default ``frequency_hz``, ``real``,
``imag``) and renames covariate columns (``temperature_c=T``); every other numeric column is
kept as a covariate.

Units: the frequency and the values are converted to SI (Hz; Pa, N/m, m/N, (m/s)/N or
(m/s^2)/N) by a factor from :data:`VALUE_UNITS` / :data:`FREQUENCY_UNITS`, taken from the
caller (the CLI's flags) or, when the caller gives none, from the file's units row.

Sweeps (test conditions), :func:`group_rows`:

* ``group_by=COLUMN``: rows with one value of that column (the instrument's set/step number)
  form one sweep;
* ``tolerance=TOL``: the condition covariates are clustered, values closer than TOL to their
  neighbour (sorted) belong to one level (a temperature that drifts within a sweep);
* neither: rows with equal values in every condition column form one sweep (the old rule).

Covariate values stay per point (as measured) in the returned conditions; a condition's
level is their mean. Sweeps with fewer than ``MIN_POINTS`` points are dropped and listed.
"""
from __future__ import annotations

import csv
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dva_offline.isolator.files import MAX_FRF_POINTS, append_numeric_row
from dva_offline.isolator.frf_data import MIN_POINTS, FrfData, condition_columns

FREQUENCY_UNITS = {"hz": 1.0, "khz": 1e3, "rad/s": 1.0 / (2 * np.pi), "1/s": 1.0}
# factor to SI per quantity family; the SI unit of each family is the first entry
VALUE_UNITS = {
    "modulus": {"pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9, "n/mm2": 1e6, "n/mm^2": 1e6},
    "stiffness": {"n/m": 1.0, "n/mm": 1e3, "kn/m": 1e3, "kn/mm": 1e6},
    "receptance": {"m/n": 1.0, "mm/n": 1e-3, "um/n": 1e-6},
    "mobility": {"(m/s)/n": 1.0, "m/s/n": 1.0, "(mm/s)/n": 1e-3, "mm/s/n": 1e-3},
    "accelerance": {"(m/s^2)/n": 1.0, "m/s^2/n": 1.0, "m/s2/n": 1.0, "g/n": 9.80665},
}
QUANTITY_FAMILY = {"stiffness": ("stiffness", "modulus"), "modulus": ("modulus",),
                   "receptance": ("receptance",), "mobility": ("mobility",),
                   "accelerance": ("accelerance",)}
ROLES = ("frequency", "real", "imag")
DEFAULT_COLUMNS = {"frequency": "frequency_hz", "real": "real", "imag": "imag"}


@dataclass(frozen=True)
class ColumnMap:
    """Which file columns hold what.

    Attributes
    ----------
    roles : dict
        ``frequency``, ``real``, ``imag`` -> column name in the file.
    renames : dict
        Covariate name used in the analysis -> column name in the file.
    """

    roles: dict = field(default_factory=lambda: dict(DEFAULT_COLUMNS))
    renames: dict = field(default_factory=dict)

    @classmethod
    def parse(cls, text: str | None) -> ColumnMap:
        """From ``ROLE=COLUMN,...`` (roles frequency/f, real, imag; any other name renames a
        covariate column, e.g. ``temperature_c=T``)."""
        roles, renames = dict(DEFAULT_COLUMNS), {}
        if not text:
            return cls(roles, renames)
        aliases = {"f": "frequency", "freq": "frequency", "frequency_hz": "frequency",
                   "re": "real", "im": "imag"}
        for item in text.split(","):
            if not item.strip():
                continue
            if "=" not in item:
                raise ValueError(f"--columns: {item.strip()!r} is not NAME=COLUMN")
            key, col = (s.strip() for s in item.split("=", 1))
            if not key or not col:
                raise ValueError(f"--columns: {item.strip()!r} is not NAME=COLUMN")
            key = aliases.get(key.lower(), key)
            if key in ROLES:
                roles[key] = col
            else:
                renames[key] = col
        return cls(roles, renames)


@dataclass(frozen=True)
class Table:
    """A CSV read as numbers: columns by name, the units row (if any); columns that hold a
    cell that is not a number are kept as text (``text``: name -> cells; ``not_numbers``:
    name -> the first such cell's message), used only when selected (a set column to group
    by) and otherwise ignored."""

    columns: dict
    units: dict
    n_rows: int
    text: dict = field(default_factory=dict)
    not_numbers: dict = field(default_factory=dict)

    def require_numeric(self, name: str) -> None:
        """Refuse a selected column that is text, naming its first cell that is no number."""
        if name in self.not_numbers:
            raise ValueError(self.not_numbers[name])


def _sniff_delimiter(line: str) -> str:
    counts = {d: line.count(d) for d in (",", ";", "\t")}
    return max(counts, key=counts.get) if max(counts.values()) else ","


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _text_lines(path: Path):
    """The file's lines that are neither blank nor comments, read one at a time."""
    with path.open(newline="", encoding="utf-8-sig") as fh:
        for line in fh:
            if line.strip() and not line.lstrip().startswith("#"):
                yield line.rstrip("\r\n")


def read_table(path) -> Table:
    """Read a numeric CSV with a header row and an optional units row (module docstring).

    Read row by row, at most :data:`~dva_offline.isolator.files.MAX_FRF_POINTS` rows: a
    larger file is refused there, not read to its end. Errors name the file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        return _read_rows(path)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text (byte at offset {exc.start}); a CSV file "
                         "is expected") from None
    except csv.Error as exc:  # e.g. NUL bytes: a binary file
        raise ValueError(f"{path}: not CSV text ({exc})") from None


def _read_rows(path: Path) -> Table:
    lines = _text_lines(path)
    first = next(lines, None)
    if first is None:
        raise ValueError(f"{path}: file is empty")
    delim = _sniff_delimiter(first)
    header = [name.strip() for name in next(csv.reader([first], delimiter=delim))]
    if len(set(header)) != len(header):
        raise ValueError(f"{path}: duplicate column names in header {header}")
    units: dict = {}
    values = array("d")  # flat, row after row: 8 bytes a value
    text: dict = {}  # column index -> its cells as text, once one is not a number
    not_numbers: dict = {}
    rows = 0
    for i, row in enumerate(csv.reader(lines, delimiter=delim)):
        if i == 0 and not any(_is_number(c) for c in row if c.strip()):  # (a text column
            # makes a data row non-numeric too: a units row has no number at all)
            units = {name: cell.strip() for name, cell in zip(header, row)}
            continue
        try:
            append_numeric_row(values, row, header, path, i + 2, rows, MAX_FRF_POINTS)
        except ValueError:
            if len(row) != len(header) or rows == MAX_FRF_POINTS:
                raise
            # a text column (a file name, a sample label): kept as text, NaN among the
            # numbers; an error only if the analysis selects it
            del values[rows * len(header):]
            for j, (name, cell) in enumerate(zip(header, row)):
                if j not in text and not _is_number(cell):
                    text[j] = [str(x) for x in values[j::len(header)]]
                    not_numbers[name] = (f"{path}: line {i + 2}, column {name!r}: "
                                         f"{cell[:40]!r} is not a number")
                values.append(float(cell) if _is_number(cell) else np.nan)
        for j, cells in text.items():
            cells.append(row[j].strip())
        rows += 1
    if not rows:
        raise ValueError(f"{path}: no data rows")
    data = np.frombuffer(values, dtype=float).reshape(rows, len(header))
    numeric = {name: data[:, j].copy() for j, name in enumerate(header) if j not in text}
    return Table(numeric, units, rows, {header[j]: cells for j, cells in text.items()},
                 not_numbers)


def _factor(unit: str, table: dict, what: str) -> float:
    key = unit.strip().lower().replace(" ", "").replace("·", "")
    if key not in table:
        raise ValueError(f"unknown {what} unit {unit!r}; known: {', '.join(table)}")
    return table[key]


def unit_factor(quantity: str, unit: str | None) -> float:
    """Factor from ``unit`` to the SI unit of ``quantity``'s values (1 for None)."""
    if unit is None:
        return 1.0
    known = {}
    for family in QUANTITY_FAMILY[quantity]:
        known.update(VALUE_UNITS[family])
    return _factor(unit, known, f"{quantity} value")


@dataclass(frozen=True)
class Grouping:
    """How the rows were split into sweeps (reported)."""

    method: str
    columns: tuple
    n_conditions: int
    dropped: tuple  # (description, n_points) of sweeps too short to use
    covariate_values: str = "per point, as measured (a condition's level is their mean)"

    def describe(self) -> str:
        text = f"{self.n_conditions} conditions by {self.method}"
        if self.dropped:
            text += "; dropped " + "; ".join(f"{d} ({n} points < {MIN_POINTS})"
                                              for d, n in self.dropped)
        return text


def _cluster(values: np.ndarray, tolerance: float) -> np.ndarray:
    """Level index of each value: sorted values split where the gap exceeds ``tolerance``."""
    order = np.argsort(values, kind="stable")
    gaps = np.diff(values[order]) > tolerance
    labels = np.empty(values.size, dtype=int)
    labels[order] = np.concatenate([[0], np.cumsum(gaps)])
    return labels


def group_rows(covariates: dict, n_rows: int, group_by: str | None = None,
               tolerance: float | None = None, columns=None) -> tuple[np.ndarray, Grouping]:
    """Condition label of each row (module docstring) and how it was found.

    ``columns``: the condition covariates (default: every column with few distinct values, or
    with ``tolerance`` every column that varies).
    """
    if group_by is not None and tolerance is not None:
        raise ValueError("give --group-by or --covariate-tolerance, not both")
    if group_by is not None:
        if group_by not in covariates:
            raise ValueError(f"--group-by column {group_by!r} not found; have "
                             f"{sorted(covariates)}")
        _, labels = np.unique(covariates[group_by], return_inverse=True)
        return labels.reshape(-1), Grouping(f"the set column {group_by!r}", (group_by,),
                                            int(labels.max()) + 1, ())
    if columns is None:
        if tolerance is None:
            columns = condition_columns(covariates, n_rows)
        else:
            columns = [n for n, c in covariates.items() if np.ptp(c) > 0]
    for name in columns:
        if name not in covariates:
            raise ValueError(f"condition column {name!r} not found; have {sorted(covariates)}")
    if not columns:
        return np.zeros(n_rows, dtype=int), Grouping("a single sweep", (), 1, ())
    if tolerance is not None:
        if not tolerance > 0:
            raise ValueError(f"--covariate-tolerance must be > 0, got {tolerance}")
        keys = np.column_stack([_cluster(np.asarray(covariates[n], float), tolerance)
                                for n in columns])
        method = f"covariate levels within {tolerance:g} of each other ({', '.join(columns)})"
    else:
        keys = np.column_stack([np.asarray(covariates[n], float) for n in columns])
        method = f"equal values of {', '.join(columns)}"
    _, first, labels = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    # number the conditions in order of their first row
    rank = np.empty(first.size, dtype=int)
    rank[np.argsort(first)] = np.arange(first.size)
    labels = rank[np.asarray(labels).reshape(-1)]
    return labels, Grouping(method, tuple(columns), int(labels.max()) + 1, ())


def conditions_from_table(table: Table, quantity: str, column_map: ColumnMap | None = None,
                          frequency_unit: str | None = None, value_unit: str | None = None,
                          group_by: str | None = None, tolerance: float | None = None,
                          covariates=None, internal_quantity: str | None = None
                          ) -> tuple[list[FrfData], Grouping, dict]:
    """Sweeps of an FRF table in SI units.

    Parameters
    ----------
    table : Table
    quantity : str
        ``stiffness``, ``modulus``, ``receptance``, ``mobility`` or ``accelerance``.
    column_map : ColumnMap, optional
    frequency_unit, value_unit : str, optional
        Units of the file (default: the file's units row, else SI).
    group_by, tolerance : optional
        See :func:`group_rows`.
    covariates : sequence of str, optional
        Condition covariates (analysis names); default every covariate that varies.
    internal_quantity : str, optional
        Quantity stored in the returned :class:`FrfData` (default ``quantity``; ``modulus``
        is stored as ``stiffness``, a modulus being a stiffness per unit geometry factor).

    Returns
    -------
    conditions, grouping, info
        ``info``: the units used and where they came from, the column map.
    """
    cmap = column_map or ColumnMap()
    cols = table.columns
    for col in cmap.roles.values():  # a selected column must be numbers
        table.require_numeric(col)
    missing = [c for c in cmap.roles.values() if c not in cols]
    if missing:
        raise ValueError(f"missing column(s) {missing}; found {list(cols)} (map them with "
                         "--columns frequency=NAME,real=NAME,imag=NAME)")
    units_used = {}

    def pick(role, given, table_units, what):
        col = cmap.roles[role]
        from_file = table.units.get(col, "")
        if given is not None:
            factor = _factor(given, table_units, what)
            if from_file and from_file.strip().lower() != given.strip().lower():
                try:
                    file_factor = _factor(from_file, table_units, what)
                except ValueError:
                    file_factor = None
                if file_factor is not None and not np.isclose(file_factor, factor):
                    raise ValueError(f"column {col!r}: the file's units row says {from_file!r},"
                                     f" the flag says {given!r}")
            units_used[role] = f"{given} (flag)"
            return factor
        if from_file and from_file not in ("-", ""):
            units_used[role] = f"{from_file} (the file's units row)"
            return _factor(from_file, table_units, what)
        units_used[role] = "SI (no unit given)"
        return 1.0

    value_table = {}
    for family in QUANTITY_FAMILY[quantity]:
        value_table.update(VALUE_UNITS[family])
    f = cols[cmap.roles["frequency"]] * pick("frequency", frequency_unit, FREQUENCY_UNITS,
                                             "frequency")
    scale_re = pick("real", value_unit, value_table, f"{quantity} value")
    scale_im = pick("imag", value_unit, value_table, f"{quantity} value")
    y = cols[cmap.roles["real"]] * scale_re + 1j * cols[cmap.roles["imag"]] * scale_im
    for name, arr in (("frequency", f), ("value", y)):
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise ValueError(f"{name} is NaN or infinite in data row {bad[0] + 1}")
    used = set(cmap.roles.values())
    renamed = {col: name for name, col in cmap.renames.items()}
    for name, col in cmap.renames.items():
        table.require_numeric(col)
        if col not in cols:
            raise ValueError(f"--columns {name}={col}: no column {col!r}; found {list(cols)}")
    cov = {renamed.get(n, n): c for n, c in cols.items() if n not in used}
    if covariates is not None:
        for name in covariates:
            table.require_numeric(cmap.renames.get(name, name))
            if name not in cov:
                raise ValueError(f"covariate {name!r} not found; have {sorted(cov)}")
    group_key = renamed.get(group_by, group_by) if group_by is not None else None
    if group_by is not None and group_by in cmap.renames:
        group_key = group_by
    group_cov = cov
    if group_by is not None and group_by in table.text:  # sweeps named by text labels
        names = {}  # label -> code, in order of first appearance
        codes = np.array([names.setdefault(x, len(names)) for x in table.text[group_by]],
                         float)
        group_cov, group_key = {**cov, group_by: codes}, group_by
    labels, grouping = group_rows(group_cov, table.n_rows, group_key, tolerance,
                                  None if covariates is None or group_by is not None
                                  else list(covariates))
    stored = internal_quantity or ("stiffness" if quantity == "modulus" else quantity)
    conditions, dropped = [], []
    for label in range(grouping.n_conditions):
        rows = np.nonzero(labels == label)[0]
        rows = rows[np.argsort(f[rows], kind="stable")]
        where = ", ".join(f"{n} = {np.mean(group_cov[n][rows]):g}"
                          for n in grouping.columns) or "all"
        if rows.size < MIN_POINTS:
            dropped.append((f"condition {where}", int(rows.size)))
            continue
        if np.any(np.diff(f[rows]) <= 0):
            raise ValueError(f"condition {where}: a frequency repeats within the sweep; the "
                             "rows mix several sweeps (group them with --group-by COLUMN or "
                             "--covariate-tolerance TOL)")
        conditions.append(FrfData(f[rows], y[rows], stored,
                                  {n: c[rows] for n, c in cov.items()}))
    if not conditions:
        sizes = [n for _, n in dropped]
        raise ValueError(f"no condition has at least {MIN_POINTS} points ({grouping.method}: "
                         f"{len(sizes)} conditions of {min(sizes)}-{max(sizes)} points); the "
                         "covariate may vary within a sweep: group with --group-by COLUMN or "
                         "--covariate-tolerance TOL")
    grouping = Grouping(grouping.method, grouping.columns, len(conditions), tuple(dropped))
    info = {"units": units_used, "columns": dict(cmap.roles), "renamed": dict(cmap.renames),
            "units_row": dict(table.units),
            "ignored_text_columns": sorted(n for n in table.text if n != group_by)}
    return conditions, grouping, info


def write_table(path, frequency_hz, values, covariates: dict | None = None) -> None:
    """Write ``frequency_hz,real,imag`` plus covariate columns, atomically (a reader never
    sees half a file; a failed write leaves no file)."""
    from aero_dva.atomic_io import atomic_output

    f = np.asarray(frequency_hz, dtype=float)
    v = np.asarray(values, dtype=complex)
    extra = covariates or {}
    cols = [f, v.real, v.imag] + [np.asarray(c, dtype=float) for c in extra.values()]
    with atomic_output(path, "w") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(["frequency_hz", "real", "imag", *extra])
        for row in zip(*cols):
            writer.writerow([repr(float(x)) for x in row])
