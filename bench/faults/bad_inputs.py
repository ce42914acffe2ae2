"""The malformed (and valid) input files of the CLI fault matrix (:mod:`bench.faults.cli_matrix`):
per input format, a writer per kind of damage, and the kinds that apply to each format."""
from __future__ import annotations

import functools
import io
import json
import math
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

# a training plan small enough to write in a second
SMALL_PLAN = ["--ratios", "0.8:0.81:0.01", "--factors", "1.0", "--n-damping", "3"]
HUGE_LINES = 10_000_000
DEEP_LEVELS = 3000  # nesting of the deep-nesting kind (Python's recursion limit is 1000)
HUGE_INTEGER = 10**400  # the huge-integer kind: no float holds it
ODD_DIR = "dir with spaces, ünïcødé ✈"
ODD_NAME = "mesure n°1 — données"

# Input formats: name -> file suffix.
SUFFIX = {"frf": ".csv", "series": ".csv", "stepped": ".csv", "static": ".csv", "uff": ".uff",
          "wing": ".yaml", "section": ".yaml", "scenario": ".yaml", "schedule": ".json",
          "network": ".npz", "bag": ".mcap", "plan": ".json"}
CSV_FORMATS = ("frf", "series", "stepped", "static")


# --------------------------------------------------------------------------------------------
# Input files
# --------------------------------------------------------------------------------------------

def _frf_rows(n: int = 200) -> tuple[list[str], np.ndarray]:
    """A Maxwell-Voigt receptance (Table 4.1 system F of the study) at ``n`` frequencies."""
    from dva_offline.isolator.maxwell_model import MaxwellModel, frf

    model = MaxwellModel(1.0, 12e3, 40.0, (12e3, 24e3), (80.0, 2000.0))
    f = np.linspace(0.5, 50.0, n)
    h = frf(model, 2 * np.pi * f, "receptance")
    return ["frequency_hz", "real", "imag"], np.column_stack([f, h.real, h.imag])


def _stepped_rows() -> tuple[list[str], np.ndarray]:
    """Steps through the resonance of a lightly damped Voigt system (17.4 Hz, 2 %)."""
    from dva_offline.isolator.maxwell_model import MaxwellModel, frf

    f = np.linspace(5.0, 30.0, 126)
    h = frf(MaxwellModel(1.0, 12e3, 8.8), 2 * np.pi * f, "receptance")
    return ["frequency_hz", "real", "imag"], np.column_stack([f, h.real, h.imag])


def _series_rows(n: int = 20_000) -> tuple[list[str], np.ndarray]:
    """White force through a lightly damped 25 Hz resonance, sampled at 1 kHz."""
    from scipy import signal

    rng = np.random.default_rng(0)
    fs = 1000.0
    force = rng.normal(0.0, 10.0, n)
    system = signal.cont2discrete(([1.0], [1.0, 2 * 0.05 * 157.0, 157.0**2]), 1 / fs)
    response = signal.lfilter(np.ravel(system[0]), system[1], force)
    return ["time_s", "force_n", "response_m"], np.column_stack([np.arange(n) / fs, force,
                                                                  response])


def _static_rows() -> tuple[list[str], np.ndarray]:
    x = np.concatenate([np.linspace(-2e-3, 2e-3, 50), np.linspace(2e-3, -2e-3, 50)])
    load = 1.2e4 * x + np.concatenate([np.full(50, -2.0), np.full(50, 2.0)])
    return ["deflection_m", "load_n"], np.column_stack([x, load])


def _csv_text(header: list[str], rows: np.ndarray) -> str:
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in row) for row in rows]
    return "\n".join(lines) + "\n"


def write_binary(path: Path) -> None:
    # NULs and bytes that are not UTF-8, as a wrong file picked by accident would have.
    path.write_bytes(np.random.default_rng(1234).integers(0, 256, 4096, dtype=np.uint8)
                     .tobytes() + b"\x00\xff\xfe")


def write_huge(path: Path, fmt: str) -> None:
    """Ten million lines: rows that would each be valid (increasing abscissa) where a CSV is
    expected, else a line of text repeated."""
    header, tail = {"frf": ("frequency_hz,real,imag", ",1e-06,-1e-07"),
                    "stepped": ("frequency_hz,real,imag", ",1e-06,-1e-07"),
                    "series": ("time_s,force_n,response_m", ",1.0,0.5"),
                    "static": ("deflection_m,load_n", ",1.0")}.get(fmt, (None, None))
    step = 100_000  # lines per write: the writer stays small
    with open(path, "w", encoding="ascii") as out:
        if header is None:
            line = "# padding\n"
            for _ in range(HUGE_LINES // step):
                out.write(line * step)
            return
        out.write(header + "\n")
        for first in range(1, HUGE_LINES, step):  # the header is line 1
            last = min(first + step, HUGE_LINES)
            out.write((tail + "\n").join(map(str, range(first, last))) + tail + "\n")


def _write_uff(path: Path) -> None:
    from dva_offline.isolator.files import write_uff58

    _, rows = _frf_rows()
    write_uff58(path, rows[:, 0], rows[:, 1] + 1j * rows[:, 2], "receptance")


def _wing_dict() -> dict:
    from aero_dva.wing.wing_io import reference_wing_path

    return yaml.safe_load(Path(reference_wing_path()).read_text(encoding="utf-8"))


SECTION = dict(semichord=1.0, mass_ratio=20.0, radius_of_gyration_sq=0.24, frequency_ratio=0.4,
               static_unbalance=0.1, elastic_axis=-0.2, pitch_frequency=1.0, air_density=1.0)


def _scenario_dict(name: str = "scenario_ramp.yaml") -> dict:
    from aero_dva import data_files

    return yaml.safe_load(Path(data_files.data_file(name)).read_text(encoding="utf-8"))


def _schedule_dict() -> dict:
    from aero_dva.control.airspeed_schedule import AirspeedSchedule
    from aero_dva.control.schedule_io import schedule_to_dict
    from aero_dva.flight.damper import DAMPER_RANGE

    return schedule_to_dict(AirspeedSchedule(a0=-2000.0, a1=25.0, airspeed_range=(95.0, 120.0),
                                             damping_range=DAMPER_RANGE))


@functools.lru_cache(maxsize=1)
def _plan_text() -> str:
    """A small valid training plan (2 airspeeds x 3 c2), made by ``dva train plan``."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "plan.json"
        subprocess.run([sys.executable, "-m", "dva_offline.cli", "train", "plan",
                        *SMALL_PLAN, "--out", str(path)], check=True, capture_output=True,
                       timeout=300)
        return path.read_text(encoding="utf-8")


def _plan_dict() -> dict:
    return json.loads(_plan_text())


def _write_network(path: Path, *, nan: bool = False, header: bool = True,
                   header_fields: dict | None = None, deep_field: str | None = None,
                   declared_shape: tuple | None = None) -> None:
    """A valid 33-input network, or one damaged: NaN in a centre, no header, header fields
    changed, one header field a nesting of :data:`DEEP_LEVELS` lists, or the centres' .npy
    header declaring ``declared_shape`` over the few bytes stored."""
    from aero_dva.control.rbf_io import save_rbf_network
    from aero_dva.control.rbf_network import InputScaling, RBFNetwork

    dim = 33
    centres = np.random.default_rng(2).uniform(0.0, 1.0, (4, dim))
    if nan:
        centres[1, 3] = np.nan
    network = RBFNetwork(centres=np.nan_to_num(centres), output_weights=np.ones(4),
                         output_bias=0.0, spread=1.0,
                         scaling=InputScaling(np.zeros(dim), np.ones(dim)),
                         input_names=tuple(f"x{i}" for i in range(dim)),
                         input_units=("1",) * dim, output_name="c2", output_unit="N s/m")
    tmp = path.with_name("valid_" + path.name)
    save_rbf_network(network, tmp)
    with np.load(tmp, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    tmp.unlink()
    if nan:
        arrays["centres"] = centres
    if not header:
        arrays.pop("header")
    if header_fields or deep_field:
        fields = {**json.loads(str(arrays["header"])), **(header_fields or {})}
        text = json.dumps(fields)
        if deep_field:
            fields[deep_field] = "__DEEP__"
            text = json.dumps(fields).replace('"__DEEP__"', deep_list_text())
        arrays["header"] = np.array(text)
    with open(path, "wb") as stream:
        np.savez(stream, **arrays)
    if declared_shape is not None:
        _replace_member(path, "centres.npy", npy_member(declared_shape, "<f8", b"\0" * 64))


def npy_member(shape, descr: str, data: bytes) -> bytes:
    """An .npy file whose header declares ``shape`` and ``descr`` over the bytes ``data``."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False,
                                                  "shape": tuple(shape)})
    return buffer.getvalue() + data


def _replace_member(path: Path, name: str, data: bytes) -> None:
    with zipfile.ZipFile(path) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    members[name] = data
    with zipfile.ZipFile(path, "w") as archive:
        for member, content in members.items():
            archive.writestr(member, content)


def deep_list_text(levels: int | None = None) -> str:
    """``levels`` (default :data:`DEEP_LEVELS`) nested flow lists around 1: valid YAML and
    JSON that recursive parsers cannot build."""
    levels = DEEP_LEVELS if levels is None else levels
    return "[" * levels + "1" + "]" * levels


def _deep_yaml(path: Path, data: dict, *keys) -> None:
    text = yaml.safe_dump(_with(data, *keys, "__DEEP__"), sort_keys=False)
    path.write_text(text.replace("__DEEP__", deep_list_text(), 1), encoding="utf-8")


def _deep_json(path: Path, data: dict, *keys) -> None:
    text = json.dumps(_with(data, *keys, "__DEEP__"))
    path.write_text(text.replace('"__DEEP__"', deep_list_text(), 1), encoding="utf-8")


def _write_bag_without_topics(path: Path) -> None:
    """A complete, valid bag directory holding only damper commands."""
    from aero_dva.bag.writer import BagWriter

    with BagWriter(path) as writer:
        writer.add_topic("/dva/damper_command", "dva_msgs/msg/DamperCommand")
        for i in range(10):
            writer.write("/dva/damper_command", {"header": {"stamp": {"sec": i, "nanosec": 0},
                                                            "frame_id": ""},
                                                 "damping": 500.0, "source": "fixed"},
                         log_time_ns=i * 10**9)


def _yaml(path: Path, data) -> None:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")


def _with(data: dict, *keys_value) -> dict:
    """A deep copy of ``data`` with one nested key set (or removed, value ``...``)."""
    out = json.loads(json.dumps(data))
    *keys, value = keys_value
    node = out
    for key in keys[:-1]:
        node = node[key]
    if value is ...:
        node.pop(keys[-1])
    else:
        node[keys[-1]] = value
    return out


def _json_nan(path: Path, data: dict, key: str) -> None:
    path.write_text(json.dumps(_with(data, key, float("nan"))), encoding="utf-8")


def _frf_variant(path: Path, change: Callable[[np.ndarray], np.ndarray],
                 header: list[str] | None = None) -> None:
    names, rows = _frf_rows()
    rows = change(rows.copy())
    names = header or names
    path.write_text(_csv_text(names, rows[:, :len(names)]), encoding="utf-8")


def _set(rows: np.ndarray, index, value) -> np.ndarray:
    rows[index] = value
    return rows


# format -> kind -> writer(path). "valid" is the content of the odd-path ok cases.
WRITERS: dict[str, dict[str, Callable[[Path], None]]] = {
    "frf": {
        "valid": lambda p: p.write_text(_csv_text(*_frf_rows()), encoding="utf-8"),
        "missing-columns": lambda p: _frf_variant(p, lambda r: r, ["frequency_hz", "real"]),
        "nan": lambda p: _frf_variant(p, lambda r: _set(r, (10, 1), np.nan)),
        "duplicate-frequency": lambda p: _frf_variant(p, lambda r: _set(r, (10, 0), r[9, 0])),
        "negative-frequency": lambda p: _frf_variant(p, lambda r: _set(r, (slice(None), 0),
                                                                       r[:, 0] - 10.0)),
    },
    "stepped": {
        "valid": lambda p: p.write_text(_csv_text(*_stepped_rows()), encoding="utf-8"),
        "missing-columns": lambda p: p.write_text(
            _csv_text(["frequency_hz", "force_amplitude_n"], _stepped_rows()[1][:, :2]),
            encoding="utf-8"),
        "nan": lambda p: p.write_text(
            _csv_text(_stepped_rows()[0], _set(_stepped_rows()[1], (7, 2), np.nan)),
            encoding="utf-8"),
        "duplicate-frequency": lambda p: p.write_text(
            _csv_text(_stepped_rows()[0], _set(_stepped_rows()[1], (7, 0), 5.8)),
            encoding="utf-8"),
        "negative-frequency": lambda p: p.write_text(
            _csv_text(_stepped_rows()[0], _set(_stepped_rows()[1], (0, 0), -5.0)),
            encoding="utf-8"),
    },
    "series": {
        "valid": lambda p: p.write_text(_csv_text(*_series_rows()), encoding="utf-8"),
        "missing-columns": lambda p: p.write_text(
            _csv_text(["time_s", "response_m"], _series_rows()[1][:, [0, 2]]), encoding="utf-8"),
        "nan": lambda p: p.write_text(
            _csv_text(_series_rows()[0], _set(_series_rows()[1], (100, 1), np.nan)),
            encoding="utf-8"),
        "duplicate-time": lambda p: p.write_text(
            _csv_text(_series_rows()[0], _set(_series_rows()[1], (100, 0), 0.099)),
            encoding="utf-8"),
    },
    "static": {
        "valid": lambda p: p.write_text(_csv_text(*_static_rows()), encoding="utf-8"),
        "missing-columns": lambda p: p.write_text(
            _csv_text(["deflection_m"], _static_rows()[1][:, :1]), encoding="utf-8"),
        "nan": lambda p: p.write_text(
            _csv_text(_static_rows()[0], _set(_static_rows()[1], (5, 1), np.nan)),
            encoding="utf-8"),
    },
    "uff": {
        "valid": lambda p: _write_uff(p),
    },
    "wing": {
        "valid": lambda p: _yaml(p, _wing_dict()),
        "syntax-error": lambda p: p.write_text("wing: {mass: [1000.0\n", encoding="utf-8"),
        "missing-keys": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", ...)),
        "nan": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", float("nan"))),
        "negative": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", -1000.0)),
        "deep-nesting": lambda p: _deep_yaml(p, _wing_dict(), "wing", "mass"),
        "huge-integer": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", HUGE_INTEGER)),
    },
    "section": {
        "valid": lambda p: _yaml(p, SECTION),
        "syntax-error": lambda p: p.write_text("semichord: 1.0\n  - mass_ratio\n",
                                               encoding="utf-8"),
        "missing-keys": lambda p: _yaml(p, _with(SECTION, "mass_ratio", ...)),
        "nan": lambda p: _yaml(p, _with(SECTION, "mass_ratio", float("nan"))),
        "negative-frequency": lambda p: _yaml(p, _with(SECTION, "pitch_frequency", -1.0)),
        "deep-nesting": lambda p: _deep_yaml(p, SECTION, "mass_ratio"),
        "huge-integer": lambda p: _yaml(p, _with(SECTION, "mass_ratio", HUGE_INTEGER)),
    },
    "scenario": {
        "syntax-error": lambda p: p.write_text("airspeed: {kind: ramp\n", encoding="utf-8"),
        "missing-keys": lambda p: _yaml(p, _with(_scenario_dict(), "airspeed", ...)),
        "nan": lambda p: _yaml(p, _with(_scenario_dict(), "duration", float("nan"))),
        "negative-frequency": lambda p: _yaml(p, _with(_scenario_dict(), "sample_rate",
                                                       -1000.0)),
        "deep-nesting": lambda p: _deep_yaml(p, _scenario_dict(), "duration"),
        "huge-integer": lambda p: _yaml(p, _with(_scenario_dict(), "duration", HUGE_INTEGER)),
    },
    "schedule": {
        "syntax-error": lambda p: p.write_text('{"a0": 1.0,', encoding="utf-8"),
        "missing-keys": lambda p: p.write_text(json.dumps(_with(_schedule_dict(), "a1", ...)),
                                               encoding="utf-8"),
        "nan": lambda p: _json_nan(p, _schedule_dict(), "a0"),
        "deep-nesting": lambda p: _deep_json(p, _schedule_dict(), "a0"),
        "huge-integer": lambda p: p.write_text(json.dumps(_with(_schedule_dict(), "a0",
                                                                HUGE_INTEGER)), encoding="utf-8"),
    },
    "plan": {
        "syntax-error": lambda p: p.write_text('{"format": ', encoding="utf-8"),
        "missing-keys": lambda p: p.write_text(json.dumps(_with(_plan_dict(), "dwells", ...)),
                                               encoding="utf-8"),
        "nan": lambda p: p.write_text(json.dumps(_with(_plan_dict(), "dwells", "airspeed",
                                                       [math.nan] * 6)), encoding="utf-8"),
        "deep-nesting": lambda p: _deep_json(p, _plan_dict(), "dwells", "airspeed"),
        "huge-integer": lambda p: p.write_text(json.dumps(_with(_plan_dict(), "dwells",
                                                                "airspeed", HUGE_INTEGER)),
                                               encoding="utf-8"),
    },
    "network": {
        "missing-keys": lambda p: _write_network(p, header=False),
        "nan": lambda p: _write_network(p, nan=True),
        "deep-nesting": lambda p: _write_network(p, deep_field="input_names"),
        "huge-integer": lambda p: _write_network(p, header_fields={"output_bias": HUGE_INTEGER}),
        "huge-shape": lambda p: _write_network(p, declared_shape=(600_000, 600_000)),
        "tiny-spread": lambda p: _write_network(p, header_fields={"spread": 1e-300}),
    },
    "bag": {
        "missing-topics": _write_bag_without_topics,
    },
}
COMMON_KINDS = ("empty", "binary", "ten-million-lines")


def kinds_of(fmt: str) -> list[str]:
    """The bad kinds that apply to a format, in table order."""
    return [*COMMON_KINDS[:2], *(k for k in WRITERS[fmt] if k != "valid"), COMMON_KINDS[2]]
