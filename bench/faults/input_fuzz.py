"""Property-based inputs for every loader of the tools (hypothesis): random bytes, random
nesting, numbers at the float limits, random array shapes, damaged valid files.

Each loader is called in this process on one generated file. The property: the loader returns,
or raises an error that ``dva`` reports as a bad input (exit 2, :func:`~dva_offline.
cli_failures.is_input_error`) in one line naming the file; nothing else (an exception that
would be an internal error or a traceback), and no file is left beside the input.
Used by tests/unit/dva_offline/test_input_fuzz.py (few examples, fixed seed) and by
bench/bench_input_fuzz.py (at least 1,000 examples per loader).
"""
from __future__ import annotations

import io
import json
import math
import os
import zipfile
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from hypothesis import strategies as st

from bench.faults import bad_inputs

DEEP = "__DEEP__"
DIGITS = "__DIGITS__"
# Numbers at and past the limits of a float, and other values where a number belongs.
EXTREME_VALUES = [10**400, -(10**400), 2**63, -(2**63), 2**62, DIGITS,
                  1.7976931348623157e308, -1.7976931348623157e308, 5e-324, 1e-300, 0, -1, 0.0,
                  -0.0, math.nan, math.inf, -math.inf, True, None, "", "1e999", "nan", [], {},
                  [1.0, 2.0], "x" * 300]
EXTREME_CELLS = ["1e309", "-1e309", "1e-400", "nan", "inf", "-inf", "", "abc", "0x10", "1_0",
                 "9" * 400, "-" + "9" * 400, "1.7976931348623157e308", "5e-324", " 1 ", "١٢"]


@dataclass(frozen=True)
class Loader:
    """One loader: its name, file suffix, the call, the valid text it starts from and its
    format family (``yaml``, ``json``, ``csv``, ``npz``, ``uff``)."""

    name: str
    suffix: str
    family: str
    load: Callable[[Path], object]
    valid: Callable[[], bytes]
    header: tuple[str, ...] = ()  # CSV columns


def _yaml_bytes(data) -> bytes:
    return yaml.safe_dump(data, sort_keys=False).encode()


def _csv_bytes(header, rows) -> bytes:
    return bad_inputs._csv_text(header, rows).encode()


def _write_network_bytes() -> bytes:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "net.npz"
        bad_inputs._write_network(path)
        return path.read_bytes()


def _uff_bytes() -> bytes:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frf.uff"
        bad_inputs._write_uff(path)
        return path.read_bytes()


def _bag_metadata() -> bytes:
    return _yaml_bytes({"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": ["bag_0.mcap"],
        "duration": {"nanoseconds": 10}, "message_count": 0, "topics_with_message_count": [],
        "compression_format": "", "compression_mode": ""}})


def _loaders() -> dict[str, Loader]:
    from aero_dva.bag.reader import bag_files
    from aero_dva.control.rbf_io import load_rbf_network
    from aero_dva.control.schedule_io import load_schedule
    from aero_dva.flight.scenario_io import load_scenario
    from aero_dva.wing.wing_io import load_section, load_wing
    from dva_offline.discrepancy.table_io import read_table
    from dva_offline.evaluation.graph_io import load_base_scenario
    from dva_offline.isolator import files as iso
    from dva_offline.training.plan_io import load_plan

    frf = bad_inputs._frf_rows(40)
    series = bad_inputs._series_rows(200)
    static = bad_inputs._static_rows()
    stepped = bad_inputs._stepped_rows()
    scenario = bad_inputs._scenario_dict()
    found = [
        Loader("wing", ".yaml", "yaml", load_wing, lambda: _yaml_bytes(bad_inputs._wing_dict())),
        Loader("section", ".yaml", "yaml", load_section,
               lambda: _yaml_bytes(bad_inputs.SECTION)),
        Loader("scenario", ".yaml", "yaml", load_scenario, lambda: _yaml_bytes(scenario)),
        Loader("evaluate scenario", ".yaml", "yaml", load_base_scenario,
               lambda: _yaml_bytes(scenario)),
        Loader("bag metadata", ".yaml", "yaml", lambda p: bag_files(_bag_dir(p)),
               _bag_metadata),
        Loader("schedule", ".json", "json", load_schedule,
               lambda: json.dumps(bad_inputs._schedule_dict()).encode()),
        Loader("training plan", ".json", "json", load_plan,
               lambda: bad_inputs._plan_text().encode()),
        Loader("rbf network", ".npz", "npz", load_rbf_network, _write_network_bytes),
        Loader("frf csv", ".csv", "csv", lambda p: iso.read_frf_csv(p, "receptance"),
               lambda: _csv_bytes(*frf), tuple(frf[0])),
        Loader("frf csv conditions", ".csv", "csv",
               lambda p: iso.read_frf_csv_conditions(p, "receptance"),
               lambda: _csv_bytes(*frf), tuple(frf[0])),
        Loader("stepped sine csv", ".csv", "csv",
               lambda p: iso.read_stepped_sine_csv(p, "receptance"),
               lambda: _csv_bytes(*stepped), tuple(stepped[0])),
        Loader("time series csv", ".csv", "csv", iso.read_time_series_csv,
               lambda: _csv_bytes(*series), tuple(series[0])),
        Loader("load-deflection csv", ".csv", "csv", iso.read_load_deflection_csv,
               lambda: _csv_bytes(*static), tuple(static[0])),
        Loader("discrepancy table", ".csv", "csv", read_table, lambda: _csv_bytes(*frf),
               tuple(frf[0])),
        Loader("uff 58", ".uff", "uff", lambda p: iso.read_uff58(p, "receptance"), _uff_bytes),
    ]
    return {loader.name: loader for loader in found}


def _bag_dir(path: Path) -> Path:
    """The bag directory whose metadata.yaml is ``path`` (the loader reads the directory)."""
    meta = path.parent / "metadata.yaml"
    if path.name != "metadata.yaml":
        os.replace(path, meta)
    return path.parent


_LOADERS: dict[str, Loader] | None = None


def loaders() -> dict[str, Loader]:
    """Every loader by name (built once: the valid files take a moment to make)."""
    global _LOADERS
    if _LOADERS is None:
        _LOADERS = _loaders()
    return _LOADERS


_VALID_CACHE: dict[str, bytes] = {}


def valid_bytes(loader: Loader) -> bytes:
    if loader.name not in _VALID_CACHE:
        _VALID_CACHE[loader.name] = loader.valid()
    return _VALID_CACHE[loader.name]


# --------------------------------------------------------------------------------------------
# Strategies
# --------------------------------------------------------------------------------------------

def _leaves(node, trail=()):
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _leaves(value, (*trail, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _leaves(value, (*trail, index))
    yield trail


def _replace(node, trail, value):
    if not trail:
        return value
    copy = json.loads(json.dumps(node))
    target = copy
    for key in trail[:-1]:
        target = target[key]
    target[trail[-1]] = value
    return copy


def _deep_text(depth: int, opener: str) -> str:
    """``depth`` nested flow lists or mappings around the number 1 (valid YAML and JSON)."""
    if opener == "{":
        return '{"a": ' * depth + "1" + "}" * depth
    return "[" * depth + "1" + "]" * depth


def _dump(family: str, data) -> str:
    if family == "yaml":
        return yaml.safe_dump(data, sort_keys=False)
    return json.dumps(data)


@st.composite
def _structured(draw, loader: Loader) -> bytes:
    """A valid YAML/JSON document with one value replaced: an extreme number, a random float
    or integer, or a nesting of random depth (flow lists or mappings)."""
    text = valid_bytes(loader).decode()
    data = yaml.safe_load(text) if loader.family == "yaml" else json.loads(text)
    trails = list(_leaves(data))
    trail = draw(st.sampled_from(trails))
    choice = draw(st.integers(0, 3))
    if choice == 0:
        value = draw(st.sampled_from(EXTREME_VALUES))
    elif choice == 1:
        value = draw(st.floats(allow_nan=True, allow_infinity=True))
    elif choice == 2:
        value = draw(st.integers(min_value=-(10**420), max_value=10**420))
    else:
        value = DEEP
    out = _dump(loader.family, _replace(data, trail, value))
    if value == DIGITS:  # an integer of 5,000 digits (no dumper writes one)
        out = out.replace(f'"{DIGITS}"' if loader.family == "json" else DIGITS, "9" * 5000, 1)
    if value == DEEP:
        depth = draw(st.integers(1, 5000))
        opener = draw(st.sampled_from("[{"))
        quoted = f'"{DEEP}"' if loader.family == "json" else DEEP
        out = out.replace(quoted, _deep_text(depth, opener), 1)
    return out.encode()


@st.composite
def _damaged(draw, loader: Loader) -> bytes:
    """The valid file cut short, with bytes changed, or with random text put in."""
    data = bytearray(valid_bytes(loader))
    kind = draw(st.integers(0, 2))
    if kind == 0:
        return bytes(data[:draw(st.integers(0, len(data)))])
    if kind == 1:
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        return bytes(data)
    at = draw(st.integers(0, len(data)))
    return bytes(data[:at]) + draw(st.text(max_size=200)).encode() + bytes(data[at:])


@st.composite
def _csv_tables(draw, loader: Loader) -> bytes:
    """A table of the loader's columns (sometimes a column more or less) with random rows of
    random or extreme cells."""
    header = list(loader.header)
    if draw(st.booleans()):
        header = header[:draw(st.integers(0, len(header)))] + draw(
            st.lists(st.sampled_from(["extra", "frequency_hz", "time_s", "temperature_c"]),
                     max_size=2))
    n_rows = draw(st.integers(0, 60))
    cell = st.one_of(st.sampled_from(EXTREME_CELLS),
                     st.floats(allow_nan=True, allow_infinity=True).map(repr),
                     st.integers(min_value=-(10**30), max_value=10**30).map(str))
    increasing = draw(st.booleans())
    lines = [",".join(header)]
    for i in range(n_rows):
        cells = [draw(cell) for _ in header]
        if increasing and cells:
            cells[0] = repr(1.0 + i * draw(st.floats(1e-9, 1e3)))
        lines.append(",".join(cells))
    return ("\n".join(lines) + "\n").encode()


@st.composite
def _npz_archives(draw, loader: Loader) -> bytes:
    """The valid network with one array's declared shape, dtype or data replaced, or with one
    header field set to an extreme value or a deep nesting."""
    with zipfile.ZipFile(io.BytesIO(valid_bytes(loader))) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    name = draw(st.sampled_from(sorted(members)))
    kind = draw(st.integers(0, 1))
    if kind == 0 or name != "header.npy":
        shape = draw(st.lists(st.integers(0, 2**40), max_size=4))
        descr = draw(st.sampled_from(["<f8", "<i8", "|u1", "<U20", "<c16", "|O", "<f2"]))
        data = draw(st.binary(max_size=256))
        members[name] = bad_inputs.npy_member(shape, descr, data)
    else:
        header = json.loads(str(np.load(io.BytesIO(members[name]), allow_pickle=False)))
        key = draw(st.sampled_from(sorted(header)))
        choice = draw(st.integers(0, 2))
        if choice == 0:
            header[key] = draw(st.sampled_from(EXTREME_VALUES))
        elif choice == 1:
            header[key] = draw(st.floats(allow_nan=True, allow_infinity=True))
        else:
            header[key] = DEEP
        text = json.dumps(header)
        if choice == 2:
            text = text.replace(f'"{DEEP}"', _deep_text(draw(st.integers(1, 5000)), "["))
        buffer = io.BytesIO()
        np.save(buffer, np.array(text))
        members[name] = buffer.getvalue()
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        for member, data in members.items():
            archive.writestr(member, data)
    return out.getvalue()


def inputs(loader: Loader) -> st.SearchStrategy[bytes]:
    """Every kind of generated file for ``loader``."""
    common = [st.binary(max_size=4096), _damaged(loader)]
    special = {"yaml": [_structured(loader)], "json": [_structured(loader)],
               "csv": [_csv_tables(loader)], "npz": [_npz_archives(loader)], "uff": []}
    return st.one_of(*common, *special[loader.family])


# --------------------------------------------------------------------------------------------
# The property
# --------------------------------------------------------------------------------------------

@dataclass
class Tally:
    """Outcomes of one loader's examples: accepted, refused (exit 2), failures (anything
    else, with a sample of each kind)."""

    accepted: int = 0
    refused: int = 0
    failures: Counter = field(default_factory=Counter)
    samples: dict = field(default_factory=dict)

    @property
    def examples(self) -> int:
        return self.accepted + self.refused + sum(self.failures.values())


def try_loader(loader: Loader, content: bytes, directory: Path) -> str | None:
    """Write ``content`` as the input file in the empty ``directory`` and load it: None when
    the loader succeeded, ``"refused"`` for an input error in one line naming the file, else a
    description of the failure. ``directory`` is emptied again."""
    from dva_offline.cli_failures import is_input_error

    path = directory / ("metadata.yaml" if loader.name == "bag metadata" else
                        "input" + loader.suffix)
    path.write_bytes(content)
    try:
        try:
            loader.load(path)
        except Exception as exc:  # noqa: BLE001 - classifying every outcome is the point
            if not is_input_error(exc):
                return f"internal: {type(exc).__name__}: {str(exc)[:120]}"
            message = str(exc)
            if "\n" in message.strip():
                return f"multi-line message: {message[:120]!r}"
            if path.name not in message and directory.name not in message:
                return f"message does not name the file: {message[:120]!r}"
            left = sorted(p.name for p in directory.iterdir()) != [path.name]
            return "left a file" if left else "refused"
        left = sorted(p.name for p in directory.iterdir()) != [path.name]
        return "left a file" if left else None
    finally:
        for item in directory.iterdir():
            item.unlink()
